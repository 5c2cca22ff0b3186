// The versions --since / --to name, and two exports of a map compared by tree id (map_changes.h).

#include "client/cli/map_changes.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>

#include "client/cli/cli_context.h"
#include "client/cli/cli_format.h"

namespace forestmap::client {
namespace {

bool AllDigits(const std::string& text) {
  return !text.empty() &&
         std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isdigit(c); });
}

// "Z", "+02:00", "-0500" or "+02": the zone's offset east of UTC in seconds; nullopt otherwise.
std::optional<int64_t> ZoneOffset(const std::string& zone) {
  if (zone.empty() || zone == "Z" || zone == "z") return 0;
  if (zone[0] != '+' && zone[0] != '-') return std::nullopt;
  std::string digits;
  for (size_t i = 1; i < zone.size(); ++i) {
    if (zone[i] == ':' && i == 3) continue;
    if (!std::isdigit(static_cast<unsigned char>(zone[i]))) return std::nullopt;
    digits += zone[i];
  }
  if (digits.size() != 2 && digits.size() != 4) return std::nullopt;
  const int hours = std::stoi(digits.substr(0, 2));
  const int minutes = digits.size() == 4 ? std::stoi(digits.substr(2)) : 0;
  if (hours > 14 || minutes > 59) return std::nullopt;
  const int64_t offset = hours * 3600 + minutes * 60;
  return zone[0] == '-' ? -offset : offset;
}

std::string Versions(const std::vector<v1::MapVersion>& versions) {
  return "versions " + std::to_string(versions.front().version()) + ".." +
         std::to_string(versions.back().version());
}

// The state of export `from`'s tree i, and whether it is compared.
bool Compared(const ExportedTrees& from, size_t i, const ChangeOptions& options) {
  return options.candidates || i >= from.states.size() || from.states[i].confirmed;
}

double Sigma(const ExportedTrees& from, size_t i, bool dbh) {
  if (i < from.states.size()) {
    const std::optional<double>& sigma =
        dbh ? from.states[i].dbh_sigma_m : from.states[i].position_sigma_m;
    if (sigma && std::isfinite(*sigma) && *sigma >= 0) return *sigma;
  }
  return dbh ? kSurveyDbhSigma : kSurveyPositionSigma;
}

}  // namespace

std::optional<int64_t> ParseIsoTime(const std::string& text) {
  int year = 0, month = 0, day = 0, consumed = 0;
  if (std::sscanf(text.c_str(), "%4d-%2d-%2d%n", &year, &month, &day, &consumed) != 3 ||
      consumed != 10) {
    return std::nullopt;
  }
  int hour = 0, minute = 0, second = 0;
  std::string zone;
  if (text.size() > 10) {
    if (text[10] != 'T' && text[10] != 't' && text[10] != ' ') return std::nullopt;
    const std::string clock = text.substr(11);
    int used = 0;
    if (std::sscanf(clock.c_str(), "%2d:%2d%n", &hour, &minute, &used) != 2 || used != 5) {
      return std::nullopt;
    }
    if (clock.size() > 5 && clock[5] == ':') {
      int more = 0;
      if (std::sscanf(clock.c_str() + 6, "%2d%n", &second, &more) != 1 || more != 2) {
        return std::nullopt;
      }
      used = 8;
    }
    zone = clock.substr(used);
  }
  const std::optional<int64_t> offset = ZoneOffset(zone);
  if (!offset || month < 1 || month > 12 || day < 1 || day > 31 || hour > 23 || minute > 59 ||
      second > 60 || year < 1970) {
    return std::nullopt;
  }
  std::tm utc{};
  utc.tm_year = year - 1900;
  utc.tm_mon = month - 1;
  utc.tm_mday = day;
  utc.tm_hour = hour;
  utc.tm_min = minute;
  utc.tm_sec = second;
  const std::time_t seconds = timegm(&utc);
  std::tm back{};
  gmtime_r(&seconds, &back);
  if (back.tm_mday != day) return std::nullopt;  // 2026-02-30
  return (static_cast<int64_t>(seconds) - *offset) * 1000;
}

const v1::MapVersion& ResolveVersion(const std::string& spec,
                                     const std::vector<v1::MapVersion>& versions,
                                     const std::string& flag, const std::string& name) {
  const std::string what = flag + " " + spec + ": ";
  if (versions.empty()) throw CommandError(what + "map '" + name + "' has no versions");
  if (AllDigits(spec)) {
    const int64_t number = spec.size() > 18 ? INT64_MAX : std::stoll(spec);
    for (const v1::MapVersion& version : versions) {
      if (version.version() == number) return version;
    }
    if (number > versions.back().version()) {
      throw CommandError(what + "map '" + name + "' has " + Versions(versions) +
                         " (see 'forestmap map history " + name + "')");
    }
    if (versions.front().version() > 1 && number >= 1) {
      throw CommandError(what + "version " + spec + " of map '" + name + "' was pruned; it keeps " +
                         Versions(versions));
    }
    throw CommandError(what + "map '" + name + "' has " + Versions(versions));
  }
  const std::optional<int64_t> at = ParseIsoTime(spec);
  if (!at) {
    throw CommandError(what +
                       "expected a version number or a date (2026-12-01, 2026-12-01T10:30:00Z)");
  }
  const v1::MapVersion* found = nullptr;
  for (const v1::MapVersion& version : versions) {
    if (version.created_unix_ms() <= *at) found = &version;
  }
  if (found) return *found;
  const v1::MapVersion& first = versions.front();
  if (first.version() == 1) {
    throw CommandError(what + "map '" + name + "' did not exist yet: it was created at " +
                       FormatUnixMs(first.created_unix_ms()));
  }
  throw CommandError(what + "the history of map '" + name + "' before version " +
                     std::to_string(first.version()) + " (" +
                     FormatUnixMs(first.created_unix_ms()) + ") was pruned");
}

const char* ChangeKindName(ChangeKind kind) {
  switch (kind) {
    case ChangeKind::kRemoved:
      return "removed";
    case ChangeKind::kNew:
      return "new";
    case ChangeKind::kGrown:
      return "grown";
    case ChangeKind::kMoved:
      return "moved";
  }
  return "?";
}

int MapChanges::Count(ChangeKind kind) const {
  return static_cast<int>(std::count_if(changes.begin(), changes.end(),
                                        [kind](const TreeChange& c) { return c.kind == kind; }));
}

MapChanges CompareExports(const ExportedTrees& before, const ExportedTrees& after,
                          const ChangeOptions& options) {
  MapChanges result;
  // Tree id -> index in each export, of the trees compared.
  const auto index = [&options](const ExportedTrees& from, int64_t& compared, int64_t& left_out) {
    std::map<int64_t, size_t> by_id;
    for (size_t i = 0; i < from.trees.size(); ++i) {
      if (!Compared(from, i, options)) {
        ++left_out;
      } else if (from.trees[i].id) {
        by_id.emplace(*from.trees[i].id, i);
        ++compared;
      }
    }
    return by_id;
  };
  const std::map<int64_t, size_t> old_ids =
      index(before, result.trees_before, result.candidates_before);
  const std::map<int64_t, size_t> new_ids =
      index(after, result.trees_after, result.candidates_after);

  std::vector<TreeChange> by_kind[4];
  for (const auto& [id, i] : old_ids) {
    const MapTreeRow& old_tree = before.trees[i];
    const auto found = new_ids.find(id);
    if (found == new_ids.end()) {
      by_kind[0].push_back({ChangeKind::kRemoved, id, old_tree, std::nullopt, 0});
      continue;
    }
    const size_t j = found->second;
    const MapTreeRow& new_tree = after.trees[j];
    if (old_tree.dbh && new_tree.dbh) {
      const double threshold = options.min_dbh_change.value_or(
          kDbhChangeSigmas * std::hypot(Sigma(before, i, true), Sigma(after, j, true)));
      if (std::abs(*new_tree.dbh - *old_tree.dbh) > threshold) {
        by_kind[2].push_back({ChangeKind::kGrown, id, old_tree, new_tree, threshold});
      }
    }
    const double threshold = options.min_move.value_or(
        kMoveSigmas * std::hypot(Sigma(before, i, false), Sigma(after, j, false)));
    if (std::hypot(new_tree.x - old_tree.x, new_tree.y - old_tree.y) > threshold) {
      by_kind[3].push_back({ChangeKind::kMoved, id, old_tree, new_tree, threshold});
    }
  }
  for (const auto& [id, j] : new_ids) {
    if (!old_ids.count(id)) {
      by_kind[1].push_back({ChangeKind::kNew, id, std::nullopt, after.trees[j], 0});
    }
  }
  for (std::vector<TreeChange>& kind : by_kind) {
    result.changes.insert(result.changes.end(), kind.begin(), kind.end());
  }
  return result;
}

}  // namespace forestmap::client
