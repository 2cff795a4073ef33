// Lafortune BRDF material presets (pbrt-v1), read at run time from config/materials.xml so that
// users can add, change or remove presets without recompiling.
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace sherd::render {

using RgbCoefficients = std::array<double, 3>;  // per colour channel: R, G, B

// One generalised-cosine lobe: max(Cxy (wo.x wi.x + wo.y wi.y) + Cz wo.z wi.z, 0) ^ n per
// channel (isotropic: Cx = Cy = Cxy).
struct LafortuneLobe {
  RgbCoefficients cxy{}, cz{}, exponent{};
};

struct LafortuneMaterial {
  std::string name;
  RgbCoefficients diffuse{};         // reflectance; the BRDF term is diffuse / pi
  std::vector<LafortuneLobe> lobes;  // at most kMaxLafortuneLobes
};

inline constexpr int kMaxLafortuneLobes = 4;  // the shader's fixed array size (pbrt presets use 3)

// All presets of a materials file. Throws sherd::InputError naming the file (and line where the
// parser knows it) for unreadable or malformed XML, missing or non-numeric coefficients.
std::vector<LafortuneMaterial> load_materials(const std::filesystem::path& file);

// The preset called `name`. Throws sherd::InputError listing the available presets when unknown.
LafortuneMaterial find_material(const std::filesystem::path& file, const std::string& name);

}  // namespace sherd::render
