#include "render/materials.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <libxml/parser.h>
#include <libxml/tree.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <memory>

namespace sherd::render {
namespace {

using XmlDoc = std::unique_ptr<xmlDoc, decltype(&xmlFreeDoc)>;

bool is_element(const xmlNode* node, const char* name) {
  return node->type == XML_ELEMENT_NODE &&
         xmlStrcmp(node->name, reinterpret_cast<const xmlChar*>(name)) == 0;
}

std::string where(const std::filesystem::path& file, const xmlNode* node) {
  return fmt::format("{}:{}", file.string(), xmlGetLineNo(node));
}

const xmlNode* only_child(const std::filesystem::path& file, const xmlNode* parent,
                          const char* name) {
  const xmlNode* found = nullptr;
  for (const xmlNode* c = parent->children; c; c = c->next) {
    if (!is_element(c, name)) continue;
    if (found)
      throw InputError(fmt::format("{}: <{}> has more than one <{}>; keep exactly one",
                                   where(file, c), reinterpret_cast<const char*>(parent->name),
                                   name));
    found = c;
  }
  if (!found)
    throw InputError(fmt::format("{}: <{}> lacks <{} r=\"…\" g=\"…\" b=\"…\"/>; add it",
                                 where(file, parent), reinterpret_cast<const char*>(parent->name),
                                 name));
  return found;
}

double number_attribute(const std::filesystem::path& file, const xmlNode* node, const char* attr) {
  std::unique_ptr<xmlChar, decltype(xmlFree)> value(
      xmlGetProp(node, reinterpret_cast<const xmlChar*>(attr)), xmlFree);
  const std::string element = reinterpret_cast<const char*>(node->name);
  if (!value)
    throw InputError(fmt::format("{}: <{}> lacks attribute {}=\"number\"; add it",
                                 where(file, node), element, attr));
  const char* text = reinterpret_cast<const char*>(value.get());
  char* end = nullptr;
  errno = 0;
  const double number = std::strtod(text, &end);
  while (end && (*end == ' ' || *end == '\t')) ++end;
  if (end == text || *end != '\0' || errno == ERANGE || !std::isfinite(number))
    throw InputError(fmt::format("{}: <{}> {}=\"{}\" is not a finite number; write e.g. 0.5",
                                 where(file, node), element, attr, text));
  return number;
}

RgbCoefficients rgb_child(const std::filesystem::path& file, const xmlNode* parent,
                          const char* name) {
  const xmlNode* node = only_child(file, parent, name);
  return {number_attribute(file, node, "r"), number_attribute(file, node, "g"),
          number_attribute(file, node, "b")};
}

LafortuneMaterial parse_material(const std::filesystem::path& file, const xmlNode* node) {
  LafortuneMaterial material;
  std::unique_ptr<xmlChar, decltype(xmlFree)> name(
      xmlGetProp(node, reinterpret_cast<const xmlChar*>("name")), xmlFree);
  if (!name || !*name.get())
    throw InputError(
        fmt::format("{}: <material> lacks a name=\"…\" attribute; add one", where(file, node)));
  material.name = reinterpret_cast<const char*>(name.get());
  material.diffuse = rgb_child(file, node, "diffuse");
  for (const xmlNode* c = node->children; c; c = c->next) {
    if (!is_element(c, "lobe")) continue;
    if (material.lobes.size() == kMaxLafortuneLobes)
      throw InputError(fmt::format("{}: material '{}' has more than {} lobes; remove some",
                                   where(file, c), material.name, kMaxLafortuneLobes));
    material.lobes.push_back(
        {rgb_child(file, c, "cxy"), rgb_child(file, c, "cz"), rgb_child(file, c, "n")});
    for (double n : material.lobes.back().exponent)
      if (n <= 0.0)
        throw InputError(
            fmt::format("{}: material '{}' has a lobe exponent {} ≤ 0; exponents "
                        "must be positive",
                        where(file, c), material.name, n));
  }
  return material;
}

}  // namespace

std::vector<LafortuneMaterial> load_materials(const std::filesystem::path& file) {
  // A private parser context so that the error (with its line) is this file's, not another
  // thread's last error.
  if (file.empty())
    throw InputError(
        "render: no materials file given (PlateSettings::materials_file); point it at "
        "config/materials.xml");
  if (!std::filesystem::is_regular_file(file))
    throw InputError(
        fmt::format("{}: materials file not found; set the path to "
                    "config/materials.xml",
                    file.string()));
  std::unique_ptr<xmlParserCtxt, decltype(&xmlFreeParserCtxt)> ctxt(xmlNewParserCtxt(),
                                                                    xmlFreeParserCtxt);
  if (!ctxt) throw InputError("materials: out of memory creating the XML parser");
  XmlDoc doc(xmlCtxtReadFile(ctxt.get(), file.c_str(), nullptr,
                             XML_PARSE_NONET | XML_PARSE_NOERROR | XML_PARSE_NOWARNING),
             xmlFreeDoc);
  if (!doc) {
    const xmlError* error = xmlCtxtGetLastError(ctxt.get());
    std::string message = error && error->message ? error->message : "unreadable";
    while (!message.empty() && (message.back() == '\n' || message.back() == ' '))
      message.pop_back();
    throw InputError(fmt::format("{}:{}: malformed XML: {}; fix the materials file", file.string(),
                                 error ? error->line : 0, message));
  }
  const xmlNode* root = xmlDocGetRootElement(doc.get());
  if (!root || !is_element(root, "materials"))
    throw InputError(fmt::format("{}: the root element must be <materials>", file.string()));
  std::vector<LafortuneMaterial> materials;
  for (const xmlNode* c = root->children; c; c = c->next) {
    if (!is_element(c, "material")) continue;
    materials.push_back(parse_material(file, c));
    for (std::size_t i = 0; i + 1 < materials.size(); ++i)
      if (materials[i].name == materials.back().name)
        throw InputError(fmt::format("{}: material '{}' is defined twice; keep one", where(file, c),
                                     materials.back().name));
  }
  if (materials.empty())
    throw InputError(fmt::format("{}: no <material> presets; add at least one", file.string()));
  return materials;
}

LafortuneMaterial find_material(const std::filesystem::path& file, const std::string& name) {
  std::vector<LafortuneMaterial> materials = load_materials(file);
  std::string available;
  for (LafortuneMaterial& material : materials) {
    if (material.name == name) return std::move(material);
    available += (available.empty() ? "" : ", ") + material.name;
  }
  throw InputError(fmt::format("{}: unknown material preset '{}'; available presets: {}",
                               file.string(), name, available));
}

}  // namespace sherd::render
