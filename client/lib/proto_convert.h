#pragma once
// Conversions between the client's types and the API messages (units and frames are the same on
// both sides: metres, radians, a_from_b poses). Field by field: nothing is validated here (the
// server validates what it receives) and nothing throws.

#include <cstdint>
#include <optional>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/core/polygon.h"
#include "client/io/tree_csv.h"
#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/relocalization.pb.h"
#include "proto/geometry_convert.h"

namespace forestmap::client {

v1::Tree ToProto(const MapTreeRow& row);
MapTreeRow FromProto(const v1::Tree& tree);

// Shared-map state of an exported tree (observations.proto).
struct TreeState {
  bool confirmed = true;                     // false: a candidate
  int64_t observations = 0;                  // observation rows behind the tree
  std::optional<double> position_sigma_m;    // m, 1-sigma horizontal
  std::optional<double> dbh_sigma_m;         // m
  std::optional<int64_t> last_seen_unix_ms;  // when a drone last saw it (none since the survey)
};
TreeState StateOf(const v1::Tree& tree);

// An unknown dbh or score (NaN) and an unknown axis (zero) are left unset.
v1::DetectedTree ToProto(const algorithms::DetectedTree& tree);

// A survey boundary (map frame, m) both ways.
v1::SurveyBoundary ToProto(const std::vector<algorithms::Polygon>& polygons);
std::vector<algorithms::Polygon> FromProto(const v1::SurveyBoundary& boundary);

using forestmap::FromProto;  // Vector3 and Pose: proto/geometry_convert.h
using forestmap::ToProto;

}  // namespace forestmap::client
