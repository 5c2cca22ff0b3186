#pragma once
// What the `forestmap` command line reads from flags and prints, kept apart from the commands so
// that it can be tested without a server.

#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "client/lib/forestmap_client.h"

namespace forestmap::client {

// Parses "X,Y,RADIUS_M" (metres), or "X,Y,YAW_DEG,RADIUS_M" of older versions (the heading is not
// used). Throws std::invalid_argument saying what is wrong, without the flag name.
PriorPosition ParsePrior(std::string_view text);

// "localized", "ambiguous", "not_found" (or "unspecified").
const char* RelocalizeStatusName(v1::RelocalizeResponse::Status status);

// Heading of the sensor x axis in the map frame, degrees counter-clockwise from map x, (-180,180].
double YawDegrees(const algorithms::Pose3& map_from_sensor);

// One line of `forestmap relocalize` output, keys in this order:
// frame (when given), status, x, y, z, qx, qy, qz, qw, yaw_deg (pose only when localized),
// lat_deg, lon_deg, ellipsoidal_height_m, true_heading_deg, grid_convergence_deg (WGS84, only
// when the server gave them: localized on a map with a CRS),
// inliers, rmse_m, confidence, server_ms, detail (the server's reason, only when not localized).
nlohmann::ordered_json RelocalizeJson(const v1::RelocalizeResponse& response,
                                      std::optional<int64_t> frame = std::nullopt);

// The CRS as `map list` shows it: "EPSG:n" for a WKT with an EPSG id, else the WKT's name, a
// short CRS as given, "-" for none; cut to 32 characters ("..."). `map show` shows it whole.
std::string ListedCrs(const std::string& crs);

// `text` (from the server) made safe to print on a terminal: control characters (C0, DEL and the
// C1 range U+0080..U+009F) and backslashes escaped as \n, \r, \t, \xNN, \u00NN, \\; other
// UTF-8 kept. `map list` and `map show` print names, descriptions and CRSs through it.
std::string TerminalSafe(std::string_view text);

// The `map list` table: NAME TREES VERSION CRS (ListedCrs) EXTENT, one map per line, aligned.
std::string FormatMapTable(const std::vector<v1::Map>& maps);

// The `map show` text: one "field: value" line per field.
std::string FormatMapDetails(const v1::Map& map);

// "x 0.00..200.00 m, y 8.80..200.00 m" or "-" for an empty map.
std::string FormatExtent(const v1::Map& map);

// The progress of a job over `total` trees (an upload, an export, a file written), done `chunk`
// at a time or less: a line "<verb>: DONE/TOTAL trees" on `err` when DONE reaches a new tenth of
// TOTAL, the last one at the end (at most 10 lines, whether or not `err` is a terminal); empty
// (nothing to call) for a job of one chunk.
std::function<void(int64_t done)> ProgressTo(std::ostream& err, std::string verb, int64_t total,
                                             int64_t chunk);

inline constexpr int64_t kExportChunk = 5000;  // trees per message the server sends, at most

// ProgressTo for an upload of `trees` trees, `chunk` per message ("uploading: ...").
UploadProgress UploadProgressTo(std::ostream& err, int64_t trees, int64_t chunk);

// UTC ISO 8601 ("2024-05-01T12:00:00Z"), or "-" for 0.
std::string FormatUnixMs(int64_t unix_ms);

}  // namespace forestmap::client
