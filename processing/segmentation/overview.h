// The segmentation overview: a top view of the scan with one colour per sherd and its id written
// on it, so that the operator sees at a glance what was found (and what was set aside).
#pragma once

#include <filesystem>

#include "core/types.h"
#include "processing/segmentation/segmentation.h"

namespace sherd::segmentation {

// Writes a PNG at true scale (pHYs) of the sherds' and rejected clusters' points seen from above
// (x to the right, y up): each sherd in its own colour with its id at its centroid, rejected
// clusters in grey. Throws sherd::ProcessingError when the file cannot be written.
void write_overview_png(const Mesh& fused, const Result& result, const std::filesystem::path& file);

}  // namespace sherd::segmentation
