// Reading and writing the station's geometry files. PCL does the parsing of PLY/PCD/OBJ/STL;
// OFF (not in PCL) is read by hand.
#pragma once

#include "core/types.h"

#include <filesystem>

namespace sherd::io {

enum class Units { Millimetres, Metres };

// Reads one model: PLY (ascii or binary, with or without colour, normals or range_grid; CRLF
// headers accepted), OBJ, OFF, STL, PCD (ascii, binary, binary_compressed). Returns millimetres
// (scaled ×1000 for Units::Metres). Every returned model has unit normals pointing out of the
// material: from the file, else from the faces' winding, else estimated from neighbours and
// oriented consistently. NaN points are dropped. Throws sherd::InputError naming the file and
// what is wrong (missing, unreadable, unknown format, corrupt, empty, non-finite).
Mesh read_model(const std::filesystem::path& file, Units units = Units::Millimetres);

// Writes a mesh (or cloud, when it has no triangles) as binary little-endian PLY with normals
// and colours where present. Throws sherd::InputError when the file cannot be written.
void write_ply(const std::filesystem::path& file, const Mesh& mesh);

// Raw views: an organised binary PCD (PointXYZRGBNormal, width × height, NaN where invalid),
// written atomically (temporary file + rename) so a crash never leaves half a view.
void write_view(const std::filesystem::path& file, const OrganisedView& view);
OrganisedView read_view(const std::filesystem::path& file);

}  // namespace sherd::io
