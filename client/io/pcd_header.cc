#include "client/io/pcd_header.h"

#include <charconv>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "client/io/scan_io_internal.h"
#include "client/io/str_cat.h"

namespace forestmap::client::pcd_internal {
namespace {

using scan_io_internal::Fail;

std::vector<std::string> Tokens(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string token; in >> token;) out.push_back(token);
  return out;
}

uint64_t ParseCount(const std::string& text, const std::string& where, const char* key) {
  uint64_t value = 0;
  const char* end = text.data() + text.size();
  const auto result = std::from_chars(text.data(), end, value);
  if (result.ec != std::errc() || result.ptr != end) {
    Fail(where, StrCat({key, " must be a non-negative integer, got '", text, "'"}));
  }
  return value;
}

// Reads one header keyword line into `header`; `where` is "FILE:LINE".
void ParseHeaderLine(const std::vector<std::string>& tokens, const std::string& where,
                     PcdHeader* header) {
  const std::string& key = tokens[0];
  const size_t n = tokens.size() - 1;
  auto single = [&]() -> const std::string& {
    if (n != 1) Fail(where, StrCat({key, " needs exactly one value"}));
    return tokens[1];
  };
  if (key == "FIELDS" || key == "COLUMNS") {
    header->fields.assign(tokens.begin() + 1, tokens.end());
  } else if (key == "SIZE") {
    for (size_t i = 1; i <= n; ++i) {
      const uint64_t size = ParseCount(tokens[i], where, "SIZE");
      if (size > 8) Fail(where, StrCat({"SIZE must be 1, 2, 4 or 8 bytes, got ", tokens[i]}));
      header->sizes.push_back(static_cast<int>(size));
    }
  } else if (key == "TYPE") {
    for (size_t i = 1; i <= n; ++i) {
      if (tokens[i].size() != 1 ||
          std::string_view("IUF").find(tokens[i][0]) == std::string::npos) {
        Fail(where, StrCat({"TYPE must be I, U or F, got '", tokens[i], "'"}));
      }
      header->types.push_back(tokens[i][0]);
    }
  } else if (key == "COUNT") {
    constexpr uint64_t kMaxCount = 1 << 16;  // values of one field in one point
    for (size_t i = 1; i <= n; ++i) {
      const uint64_t count = ParseCount(tokens[i], where, "COUNT");
      if (count > kMaxCount) {
        Fail(where, StrCat({"COUNT ", tokens[i], " is over ", std::to_string(kMaxCount),
                            " values per field (not a point cloud?)"}));
      }
      header->counts.push_back(static_cast<int>(count));
    }
  } else if (key == "WIDTH") {
    header->width = ParseCount(single(), where, "WIDTH");
    header->has_width = true;
  } else if (key == "HEIGHT") {
    header->height = ParseCount(single(), where, "HEIGHT");
  } else if (key == "POINTS") {
    header->points = ParseCount(single(), where, "POINTS");
    header->has_points = true;
  } else if (key == "DATA") {
    header->data = single();
    if (header->data != "ascii" && header->data != "binary" &&
        header->data != "binary_compressed") {
      Fail(where,
           StrCat({"DATA must be ascii, binary or binary_compressed, got '", header->data, "'"}));
    }
  } else if (key != "VERSION" && key != "VIEWPOINT") {
    Fail(where, StrCat({"unknown header keyword '", key, "'"}));
  }
}

void CheckHeader(const PcdHeader& h, const std::string& path) {
  const size_t n = h.fields.size();
  if (n == 0) Fail(path, "header has no FIELDS line");
  if (h.sizes.size() != n) Fail(path, "header SIZE does not have one entry per field");
  if (h.types.size() != n) Fail(path, "header TYPE does not have one entry per field");
  if (!h.counts.empty() && h.counts.size() != n) {
    Fail(path, "header COUNT does not have one entry per field");
  }
  for (size_t i = 0; i < n; ++i) {
    const int size = h.sizes[i];
    const bool ok = h.types[i] == 'F' ? (size == 4 || size == 8)
                                      : (size == 1 || size == 2 || size == 4 || size == 8);
    if (!ok) {
      Fail(path, StrCat({"field '", h.fields[i], "': TYPE ", std::string(1, h.types[i]),
                         " cannot have SIZE ", std::to_string(size)}));
    }
  }
  for (size_t i = 0; i < h.counts.size(); ++i) {
    // PCL drops a field with COUNT 0, so it would not be there to read.
    if (h.counts[i] < 1)
      Fail(path, StrCat({"field '", h.fields[i], "': COUNT must be at least 1"}));
  }
  for (const char* axis : {"x", "y", "z"}) {
    bool found = false;
    for (size_t i = 0; i < n; ++i) found = found || h.fields[i] == axis;
    if (!found) Fail(path, StrCat({"header FIELDS has no '", axis, "' field"}));
  }
  if (!h.has_width) Fail(path, "header has no WIDTH line");
  if (h.data.empty()) Fail(path, "header has no DATA line");
  if (h.has_points && h.points != h.width * h.height) {
    Fail(path, StrCat({"point count mismatch: POINTS ", std::to_string(h.points),
                       " but WIDTH x HEIGHT = ", std::to_string(h.width * h.height)}));
  }
  if (h.width * h.height > std::numeric_limits<uint32_t>::max()) {
    Fail(path, "too many points");
  }
}

// PCL reads on after the DATA line while lines are empty, comments, or start with a header
// keyword (prefix match; a later DATA wins). Data that begins like that would be read by PCL
// differently from this header (a later "DATA binary_compressed" whose size word asks for a GB), so
// it is refused.
void CheckDataStart(std::istream& in, int line_number, const std::string& path) {
  static constexpr const char* kKeywords[] = {"VERSION",   "FIELDS", "COLUMNS", "SIZE",
                                              "TYPE",      "COUNT",  "WIDTH",   "HEIGHT",
                                              "VIEWPOINT", "POINTS", "DATA"};
  constexpr size_t kMaxLook = 4096;  // bytes of a data line looked at
  for (int n = line_number + 1; in; ++n) {
    std::string line;
    for (int c; line.size() < kMaxLook && (c = in.get()) != EOF && c != '\n';) {
      line += static_cast<char>(c);
    }
    const std::vector<std::string> tokens = Tokens(line);
    if (tokens.empty() && !line.empty()) return;  // PCL stops at white space
    if (tokens.empty() || tokens[0][0] == '#') continue;
    for (const char* keyword : kKeywords) {
      if (tokens[0].rfind(keyword, 0) == 0) {
        Fail(StrCat({path, ":", std::to_string(n)}),
             StrCat({"data after the DATA line starts with header keyword '", keyword,
                     "' (PCL would read it as header; a second header?)"}));
      }
    }
    return;
  }
}

uint64_t PointStep(const PcdHeader& h) {
  uint64_t step = 0;
  for (size_t i = 0; i < h.fields.size(); ++i) {
    step += static_cast<uint64_t>(h.sizes[i]) * (h.counts.empty() ? 1 : h.counts[i]);
  }
  return step;
}

}  // namespace

// Parses the header by hand (PCL skips comments, and we want the offset comment and our own
// messages), and checks that binary data is long enough before PCL maps it.
PcdHeader ReadHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(path, "cannot open file for reading");
  PcdHeader header;
  std::string line;
  int line_number = 0;
  uint64_t consumed = 0;
  while (header.data.empty() && std::getline(in, line)) {
    ++line_number;
    consumed += line.size() + 1;
    if (line.size() > 1 << 16)
      Fail(path, StrCat({"line ", std::to_string(line_number),
                         ": header line too long (not a PCD file?)"}));
    const std::string where = StrCat({path, ":", std::to_string(line_number)});
    // PCL 1.13 dereferences null on a header line of only white space (" ", "\t", a CRLF "\r").
    if (!line.empty() && line[0] != '#' && Tokens(line).empty()) {
      Fail(where, "header line of only white space (PCL cannot read it; make it empty)");
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty() && line[0] == '#') {
      scan_io_internal::ParseOffsetComment(line, where, &header.offset);
      continue;
    }
    const std::vector<std::string> tokens = Tokens(line);
    if (tokens.empty()) continue;
    ParseHeaderLine(tokens, where, &header);
  }
  if (line_number == 0) Fail(path, "empty file");
  if (!header.data.empty()) CheckDataStart(in, line_number, path);
  header.data_offset = consumed;
  CheckHeader(header, path);
  if (!header.has_points) header.points = header.width * header.height;
  return header;
}

void CheckDataLength(const PcdHeader& h, const std::string& path) {
  const uint64_t file_size = std::filesystem::file_size(path);
  const uint64_t available = file_size > h.data_offset ? file_size - h.data_offset : 0;
  const uint64_t needed = h.points * PointStep(h);
  // PCL allocates points x point step before it reads ascii data, so a header must not promise
  // more values than the file has bytes (each value takes at least one).
  uint64_t values = 0;
  for (size_t i = 0; i < h.fields.size(); ++i) values += h.counts.empty() ? 1 : h.counts[i];
  if (h.data == "ascii" && h.points * values > available) {
    Fail(path, StrCat({"byte ", std::to_string(h.data_offset), ": ", std::to_string(h.points),
                       " points of ", std::to_string(values), " values cannot fit in the ",
                       std::to_string(available), " bytes of ascii data (truncated file?)"}));
  }
  if (h.data == "binary" && available < needed) {
    Fail(path, StrCat({"byte ", std::to_string(h.data_offset), ": truncated binary data: ",
                       std::to_string(h.points), " points need ", std::to_string(needed),
                       " bytes, the file has ", std::to_string(available)}));
  }
  // Size words are checked whenever they are there: with no points the uncompressed size must be
  // 0 too, or PCL allocates what the word says (2.4 GB for a 217-byte file).
  if (h.data == "binary_compressed" && (h.points > 0 || available >= 8)) {
    uint32_t sizes[2] = {0, 0};
    std::ifstream in(path, std::ios::binary);
    in.seekg(static_cast<std::streamoff>(h.data_offset));
    if (available < 8 || !in.read(reinterpret_cast<char*>(sizes), 8)) {
      Fail(path, StrCat({"byte ", std::to_string(h.data_offset),
                         ": truncated binary_compressed data (no size words)"}));
    }
    if (sizes[1] != needed || sizes[0] > available - 8) {
      Fail(path,
           StrCat({"byte ", std::to_string(h.data_offset), ": binary_compressed sizes (compressed ",
                   std::to_string(sizes[0]), ", uncompressed ", std::to_string(sizes[1]),
                   ") do not fit ", std::to_string(needed), " bytes of points and ",
                   std::to_string(available - 8), " bytes in the file"}));
    }
  }
}

}  // namespace forestmap::client::pcd_internal
