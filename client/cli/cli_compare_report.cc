#include "client/cli/cli_compare_report.h"

#include <cmath>
#include <cstdio>
#include <fstream>

#include "client/cli/cli_context.h"

namespace forestmap::client {
namespace {

constexpr double kCm = 100.0;  // cm per m, for the table

// A JSON number, or null for a figure over nothing.
nlohmann::ordered_json OrNull(const std::optional<double>& value) {
  return value ? nlohmann::ordered_json(*value) : nlohmann::ordered_json(nullptr);
}

// `format` applied to `value` times `scale`, or "-" for a figure over nothing.
std::string Figure(const char* format, const std::optional<double>& value, double scale = 1) {
  if (!value) return "-";
  char text[64];
  std::snprintf(text, sizeof(text), format, scale * *value);
  return text;
}

// The class bounds in cm with as many decimals as tell the classes apart (10-20, 2.5-5.0).
std::string ClassRange(const algorithms::DbhClassOmission& c) {
  const double width_cm = kCm * (c.max_dbh - c.min_dbh);
  int decimals = 0;
  while (decimals < 3 && std::abs(width_cm * std::pow(10, decimals) -
                                  std::round(width_cm * std::pow(10, decimals))) > 1e-6) {
    ++decimals;
  }
  char range[48];
  std::snprintf(range, sizeof(range), "%.*f-%.*f", decimals, kCm * c.min_dbh, decimals,
                kCm * c.max_dbh);
  return range;
}

std::string Number(double v) {
  if (!std::isfinite(v)) return "";
  char text[32];
  std::snprintf(text, sizeof(text), "%.4f", v);
  return text;
}

// A text field, quoted when it holds a separator, a quote or a line break.
std::string CsvText(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (const char c : text) {
    if (c == '"') quoted += '"';
    quoted += c;
  }
  return quoted + '"';
}

}  // namespace

std::string RowId(const MapTreeRow& row, int index) {
  if (row.id) return std::to_string(*row.id);
  if (row.text_id) return *row.text_id;
  return "#" + std::to_string(index + 1);
}

nlohmann::ordered_json CompareJson(const CompareReport& report) {
  const algorithms::InventoryComparison& r = report.result;
  nlohmann::ordered_json json;
  json["detected_trees"] = r.detected_trees;
  json["reference_trees"] = r.reference_trees;
  json["linked"] = r.links.size();
  json["completeness"] = OrNull(r.completeness);
  if (report.visible) {
    json["visible_reference_trees"] = report.visible->reference_trees;
    json["visible_linked"] = report.visible->linked;
    json["visible_completeness"] = OrNull(report.visible->completeness);
  }
  json["commission"] = OrNull(r.commission);
  json["position_rmse_m"] = OrNull(r.position_rmse);
  json["bias_x_m"] = OrNull(r.bias_x);
  json["bias_y_m"] = OrNull(r.bias_y);
  json["dbh_pairs"] = r.dbh_pairs;
  json["dbh_rmse_m"] = OrNull(r.dbh_rmse);
  json["dbh_bias_m"] = OrNull(r.dbh_bias);
  json["omission_by_dbh"] = nlohmann::ordered_json::array();
  for (const algorithms::DbhClassOmission& c : r.omission_by_dbh) {
    json["omission_by_dbh"].push_back({{"min_dbh_m", c.min_dbh},
                                       {"max_dbh_m", c.max_dbh},
                                       {"reference_trees", c.reference_trees},
                                       {"linked", c.linked},
                                       {"omission", c.omission}});
  }
  if (r.reference_without_dbh > 0) {  // the row of unknown DBH: bounds null
    json["omission_by_dbh"].push_back(
        {{"min_dbh_m", nullptr},
         {"max_dbh_m", nullptr},
         {"reference_trees", r.reference_without_dbh},
         {"linked", r.reference_without_dbh_linked},
         {"omission",
          1.0 - static_cast<double>(r.reference_without_dbh_linked) / r.reference_without_dbh}});
  }
  if (report.registration) {
    const CompareRegistration& t = *report.registration;
    json["registration"] = {{"rotation_deg", t.rotation_deg},
                            {"centre_x_m", t.centre_x},
                            {"centre_y_m", t.centre_y},
                            {"shift_x_m", t.shift_x},
                            {"shift_y_m", t.shift_y},
                            {"translation_x_m", t.translation_x},
                            {"translation_y_m", t.translation_y},
                            {"inliers", t.inliers},
                            {"rmse_m", t.rmse}};
  }
  return json;
}

void PrintCompareTable(const CompareReport& report, std::ostream& out) {
  const algorithms::InventoryComparison& r = report.result;
  char line[1024];
  const auto print = [&](const char* format, auto... values) {
    std::snprintf(line, sizeof(line), format, values...);
    out << line << '\n';
  };
  const int unlinked = r.detected_trees - static_cast<int>(r.links.size());
  print("%-16s %s (%d trees) vs reference %s (%d trees), links within %.2f m", "compare",
        report.detections.c_str(), r.detected_trees, report.reference.c_str(), r.reference_trees,
        report.link_distance);
  print("%-16s %zu of %d reference trees", "linked", r.links.size(), r.reference_trees);
  print("%-16s %s", "completeness",
        r.completeness ? Figure("%.1f %%", r.completeness, 100).c_str() : "- (no reference trees)");
  if (report.visible) {
    print("%-16s %s (%d of %d reference trees marked visible=1)", "  of visible",
          Figure("%.1f %%", report.visible->completeness, 100).c_str(), report.visible->linked,
          report.visible->reference_trees);
  }
  print("%-16s %s (%d of %d detections unlinked)", "commission",
        Figure("%.1f %%", r.commission, 100).c_str(), unlinked, r.detected_trees);
  if (r.position_rmse) {
    print("%-16s %.3f m (bias x %+.3f m, y %+.3f m)", "position RMSE", *r.position_rmse, *r.bias_x,
          *r.bias_y);
  } else {
    print("%-16s - (no pairs)", "position RMSE");
  }
  if (r.dbh_rmse) {
    print("%-16s %.2f cm over %d pairs (bias %+.2f cm, detected - reference)", "DBH RMSE",
          kCm * *r.dbh_rmse, r.dbh_pairs, kCm * *r.dbh_bias);
  } else {
    print("%-16s - (no pairs with both DBHs)", "DBH RMSE");
  }
  out << "omission by reference DBH class:\n";
  print("  %-12s %6s %7s %9s", "DBH cm", "trees", "linked", "omission");
  for (const algorithms::DbhClassOmission& c : r.omission_by_dbh) {
    print("  %-12s %6d %7d %8.1f%%", ClassRange(c).c_str(), c.reference_trees, c.linked,
          100 * c.omission);
  }
  if (r.reference_without_dbh > 0) {
    print("  %-12s %6d %7d %8.1f%%", "unknown DBH", r.reference_without_dbh,
          r.reference_without_dbh_linked,
          100 * (1.0 -
                 static_cast<double>(r.reference_without_dbh_linked) / r.reference_without_dbh));
  }
}

void WriteCompareLinks(const std::string& path, const std::vector<MapTreeRow>& detected,
                       const std::vector<algorithms::DetectedTree>& placed,
                       const std::vector<MapTreeRow>& reference,
                       const algorithms::InventoryComparison& result) {
  std::ofstream out(path);
  out << "detected_id,reference_id,detected_x,detected_y,reference_x,reference_y,distance_m,"
         "detected_dbh_m,reference_dbh_m,dbh_difference_m\n";
  for (const algorithms::InventoryLink& link : result.links) {
    const algorithms::DetectedTree& d = placed[link.detected];
    const MapTreeRow& r = reference[link.reference];
    const double reference_dbh = r.dbh.value_or(algorithms::kUnknown);
    out << CsvText(RowId(detected[link.detected], link.detected)) << ','
        << CsvText(RowId(r, link.reference)) << ',' << Number(d.position.x()) << ','
        << Number(d.position.y()) << ',' << Number(r.x) << ',' << Number(r.y) << ','
        << Number(link.distance) << ',' << Number(d.dbh) << ',' << Number(reference_dbh) << ','
        << Number(d.dbh - reference_dbh) << '\n';
  }
  if (!out) throw CommandError(path + ": cannot write the links");
}

void WriteCompareUnlinked(const std::string& path, const std::vector<MapTreeRow>& detected,
                          const std::vector<algorithms::DetectedTree>& placed,
                          const std::vector<MapTreeRow>& reference,
                          const algorithms::InventoryComparison& result) {
  std::ofstream out(path);
  out << "status,id,x,y,dbh_m\n";
  std::vector<bool> detected_linked(placed.size()), reference_linked(reference.size());
  for (const algorithms::InventoryLink& link : result.links) {
    detected_linked[link.detected] = reference_linked[link.reference] = true;
  }
  for (size_t i = 0; i < reference.size(); ++i) {
    if (reference_linked[i]) continue;
    const MapTreeRow& r = reference[i];
    out << "missed," << CsvText(RowId(r, static_cast<int>(i))) << ',' << Number(r.x) << ','
        << Number(r.y) << ',' << Number(r.dbh.value_or(algorithms::kUnknown)) << '\n';
  }
  for (size_t i = 0; i < placed.size(); ++i) {
    if (detected_linked[i]) continue;
    const algorithms::DetectedTree& d = placed[i];
    out << "commission," << CsvText(RowId(detected[i], static_cast<int>(i))) << ','
        << Number(d.position.x()) << ',' << Number(d.position.y()) << ',' << Number(d.dbh) << '\n';
  }
  if (!out) throw CommandError(path + ": cannot write the unlinked trees");
}

}  // namespace forestmap::client
