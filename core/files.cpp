#include "core/files.h"

#include "core/errors.h"

#include <fmt/format.h>

#include <fstream>

namespace sherd {

void write_file_atomically(const std::filesystem::path& file, std::string_view contents) {
  const auto temporary = std::filesystem::path(file.string() + ".tmp");
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << contents;
    out.close();
    if (!out) {
      throw InputError(fmt::format("cannot write {}: check that the directory is writable and the "
                                   "disk not full", temporary.string()));
    }
  }
  std::error_code error;
  std::filesystem::rename(temporary, file, error);
  if (error) {
    throw InputError(fmt::format("cannot replace {}: {}; check the directory's permissions",
                                 file.string(), error.message()));
  }
}

}  // namespace sherd
