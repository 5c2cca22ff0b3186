#pragma once
// A map's survey boundary as both stores keep it: the coordinates of a GeoJSON MultiPolygon
// ([[[[x, y], ...], hole, ...], polygon, ...]; rings without the first vertex repeated), one text
// per version that set it, "" for a version that removed it.

#include <string>

#include "storage/map_store.h"

namespace forestmap::storage::internal {

// kInvalidArgument naming the polygon and ring for a ring of fewer than 3 vertices or a vertex
// that is not finite, and for more than kMaxBoundaryVertices vertices.
void CheckBoundary(const std::string& map_name, const Boundary& boundary);

// "" for an empty boundary.
std::string EncodeBoundary(const Boundary& boundary);
// Boundary of `text` ("" -> empty); kInternal naming the map when the stored text is not one.
Boundary DecodeBoundary(const std::string& map_name, const std::string& text);

}  // namespace forestmap::storage::internal
