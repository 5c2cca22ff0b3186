#include "client/cli/cli_format.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <memory>
#include <stdexcept>

#include "client/io/csv_columns.h"
#include "client/lib/proto_convert.h"
#include "proto/enum_label.h"

namespace forestmap::client {
namespace {

std::string Printf(const char* format, double a, double b) {
  char buffer[128];
  std::snprintf(buffer, sizeof(buffer), format, a, b);
  return buffer;
}

std::string PadRight(const std::string& text, size_t width) {
  return text + std::string(width > text.size() ? width - text.size() : 0, ' ');
}

}  // namespace

PriorPosition ParsePrior(std::string_view text) {
  const std::string expected =
      "expected X,Y,RADIUS_M (3 numbers, m) or X,Y,YAW_DEG,RADIUS_M, got '" + std::string(text) +
      "'";
  std::vector<double> values;
  for (size_t start = 0; start <= text.size();) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string_view part = Trim(text.substr(start, comma - start));
    double value = 0;
    const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), value);
    if (part.empty() || ec != std::errc() || end != part.data() + part.size() ||
        !std::isfinite(value)) {
      throw std::invalid_argument("'" + std::string(part) + "' is not a number; " + expected);
    }
    values.push_back(value);
    start = comma + 1;
  }
  if (values.size() != 3 && values.size() != 4) throw std::invalid_argument(expected);
  // Four numbers: the form of older versions, whose heading the server never used.
  const PriorPosition prior{values[0], values[1], values.back()};
  if (!(prior.radius_m > 0)) {
    throw std::invalid_argument("RADIUS_M must be > 0, got '" + std::string(text) + "'");
  }
  return prior;
}

const char* RelocalizeStatusName(v1::RelocalizeResponse::Status status) {
  switch (status) {
    case v1::RelocalizeResponse::STATUS_LOCALIZED:
      return "localized";
    case v1::RelocalizeResponse::STATUS_AMBIGUOUS:
      return "ambiguous";
    case v1::RelocalizeResponse::STATUS_NOT_FOUND:
      return "not_found";
    default:
      return "unspecified";
  }
}

double YawDegrees(const algorithms::Pose3& map_from_sensor) {
  // The sensor x axis in the map frame is the first column of the rotation.
  return algorithms::YawOf(map_from_sensor.linear()) * 180.0 / M_PI;
}

nlohmann::ordered_json RelocalizeJson(const v1::RelocalizeResponse& response,
                                      std::optional<int64_t> frame) {
  nlohmann::ordered_json line;
  if (frame) line["frame"] = *frame;
  line["status"] = RelocalizeStatusName(response.status());
  if (!response.map_name().empty()) line["map"] = response.map_name();
  if (!response.rival_map_name().empty()) line["rival_map"] = response.rival_map_name();
  if (response.status() == v1::RelocalizeResponse::STATUS_LOCALIZED) {
    const v1::Pose& pose = response.map_from_sensor();
    line["x"] = pose.translation().x();
    line["y"] = pose.translation().y();
    line["z"] = pose.translation().z();
    line["qx"] = pose.rotation().x();
    line["qy"] = pose.rotation().y();
    line["qz"] = pose.rotation().z();
    line["qw"] = pose.rotation().w();
    line["yaw_deg"] = YawDegrees(FromProto(pose));
  }
  if (response.has_geodetic()) {  // maps with a CRS: WGS84
    const v1::GeodeticPose& g = response.geodetic();
    line["lat_deg"] = g.latitude_deg();
    line["lon_deg"] = g.longitude_deg();
    line["ellipsoidal_height_m"] = g.ellipsoidal_height_m();
    line["true_heading_deg"] = g.true_heading_deg();
    line["grid_convergence_deg"] = g.grid_convergence_deg();
    line["wgs84_accuracy_m"] = g.transformation_accuracy_m();  // -1: PROJ states none
    if (g.ballpark_transformation()) line["wgs84_ballpark"] = true;
  }
  line["inliers"] = response.inliers();
  line["rmse_m"] = response.rmse_m();
  line["confidence"] = response.confidence();
  line["coverage_share"] = response.coverage_share();
  line["trees_in_coverage"] = response.trees_in_coverage();
  line["server_ms"] = response.server_time_ms();
  if (response.status() == v1::RelocalizeResponse::STATUS_LOCALIZED &&
      response.covariance_size() == 36) {
    line["sigma_xy_m"] = std::sqrt(response.covariance(0) + response.covariance(7));
    line["sigma_yaw_deg"] = std::sqrt(response.covariance(35)) * 180.0 / M_PI;
  }
  if (response.status() != v1::RelocalizeResponse::STATUS_LOCALIZED &&
      response.reason() != v1::RelocalizeResponse::REASON_UNSPECIFIED) {
    std::string reason = EnumLabel(*v1::RelocalizeResponse::Reason_descriptor(), response.reason());
    for (char& c : reason) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    line["reason"] = reason;
  }
  if (response.status() != v1::RelocalizeResponse::STATUS_LOCALIZED && !response.detail().empty()) {
    line["detail"] = response.detail();  // why not: worth showing the user
  }
  if (response.has_client_stamp_ns()) line["client_stamp_ns"] = response.client_stamp_ns();
  return line;
}

std::string FormatExtent(const v1::Map& map) {
  if (!map.has_extent()) return "-";
  const v1::Box2& box = map.extent();
  return Printf("x %.2f..%.2f m, ", box.min_x(), box.max_x()) +
         Printf("y %.2f..%.2f m", box.min_y(), box.max_y());
}

UploadProgress UploadProgressTo(std::ostream& err, int64_t trees, int64_t chunk) {
  const auto progress = ProgressTo(err, "uploading", trees, chunk);
  if (!progress) return {};
  return [progress](int64_t sent, int64_t) { progress(sent); };
}

std::function<void(int64_t done)> ProgressTo(std::ostream& err, std::string verb, int64_t total,
                                             int64_t chunk) {
  static constexpr int64_t kSteps = 10;  // lines of progress per job, at most
  if (total <= chunk) return {};
  auto printed = std::make_shared<int64_t>(0);  // the last tenth printed
  return [&err, verb = std::move(verb), total, printed](int64_t done) {
    const int64_t step = std::min(kSteps, done * kSteps / total);
    if (step <= *printed) return;
    *printed = step;
    err << verb << ": " << std::min(done, total) << "/" << total << " trees" << std::endl;
  };
}

std::string FormatUnixMs(int64_t unix_ms) {
  if (unix_ms == 0) return "-";
  const std::time_t seconds = static_cast<std::time_t>(unix_ms / 1000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return buffer;
}

namespace {

constexpr size_t kCrsColumnChars = 32;  // widest CRS shown in `map list` (longer: cut with "...")

// The EPSG code of the outermost object of WKT `wkt`, its ID["EPSG",n] (WKT2) or
// AUTHORITY["EPSG","n"] (WKT1) directly inside the outer brackets; empty if it has none.
std::string WktEpsgCode(const std::string& wkt) {
  int depth = 0;
  bool quoted = false;
  for (size_t i = 0; i < wkt.size(); ++i) {
    const char c = wkt[i];
    if (c == '"') quoted = !quoted;
    if (quoted) continue;
    if (c == '[' || c == '(') ++depth;
    if (c == ']' || c == ')') --depth;
    if (depth != 1 || c != ',') continue;
    const std::string_view rest = std::string_view(wkt).substr(i + 1);
    for (const std::string_view key : {"ID[\"EPSG\",", "AUTHORITY[\"EPSG\",\""}) {
      if (!rest.starts_with(key)) continue;
      const std::string_view code = rest.substr(key.size());
      const size_t digits = code.find_first_not_of("0123456789");
      if (digits != 0 && digits != std::string_view::npos)
        return std::string(code.substr(0, digits));
    }
  }
  return "";
}

}  // namespace

std::string ListedCrs(const std::string& crs) {
  if (crs.empty()) return "-";
  std::string shown = crs;
  const size_t open = crs.find('[');
  if (open != std::string::npos) {
    const std::string code = WktEpsgCode(crs);
    const size_t name_end = crs.find('"', open + 2);
    if (!code.empty()) {
      shown = "EPSG:" + code;
    } else if (crs.compare(open + 1, 1, "\"") == 0 && name_end != std::string::npos) {
      shown = crs.substr(open + 2, name_end - open - 2);  // PROJCRS["NAME",...
    }
  }
  if (shown.size() > kCrsColumnChars) shown = shown.substr(0, kCrsColumnChars - 3) + "...";
  return shown;
}

std::string TerminalSafe(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (size_t i = 0; i < text.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    const unsigned char next = i + 1 < text.size() ? static_cast<unsigned char>(text[i + 1]) : 0;
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\r') {
      out += "\\r";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7f) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\x%02x", c);
      out += escaped;
    } else if (c == 0xc2 && next >= 0x80 && next <= 0x9f) {  // U+0080..U+009F in UTF-8
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", next);
      out += escaped;
      ++i;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

std::string FormatMapTable(const std::vector<v1::Map>& maps) {
  std::vector<std::array<std::string, 5>> cells = {{"NAME", "TREES", "VERSION", "CRS", "EXTENT"}};
  for (const v1::Map& map : maps) {
    cells.push_back({TerminalSafe(map.name()), std::to_string(map.tree_count()),
                     std::to_string(map.version()), TerminalSafe(ListedCrs(map.crs())),
                     FormatExtent(map)});
  }
  std::array<size_t, 5> width{};
  for (const auto& row : cells) {
    for (size_t i = 0; i < row.size(); ++i) width[i] = std::max(width[i], row[i].size());
  }
  std::string table;
  for (const auto& row : cells) {
    std::string line;
    for (size_t i = 0; i + 1 < row.size(); ++i) line += PadRight(row[i], width[i] + 2);
    table += line + row.back() + "\n";
  }
  return table;
}

std::string FormatMapDetails(const v1::Map& map) {
  std::string text;
  auto field = [&text](const char* name, const std::string& value) {
    text += PadRight(std::string(name) + ":", 13) + value + "\n";
  };
  field("name", TerminalSafe(map.name()));
  field("description", map.description().empty() ? "-" : TerminalSafe(map.description()));
  field("crs", map.crs().empty() ? "-" : TerminalSafe(map.crs()));
  field("version", std::to_string(map.version()));
  field("trees", std::to_string(map.tree_count()));
  field("extent", FormatExtent(map));
  if (map.has_extent()) {
    const v1::Box2& box = map.extent();
    field("size", Printf("%.2f x %.2f m", box.max_x() - box.min_x(), box.max_y() - box.min_y()));
  }
  field("boundary", map.has_boundary() ? "yes" : "no");
  field("created", FormatUnixMs(map.created_unix_ms()));
  field("updated", FormatUnixMs(map.updated_unix_ms()));
  return text;
}

}  // namespace forestmap::client
