// Writing files so that nothing is lost on failure.
#pragma once

#include <filesystem>
#include <string_view>

namespace sherd {

// Writes `contents` beside `file` and renames it over `file`: a reader (or a crash) never sees
// half a document. Throws InputError naming the file when it cannot be written or replaced.
void write_file_atomically(const std::filesystem::path& file, std::string_view contents);

}  // namespace sherd
