#include "client/io/csv_reader.h"

#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>

#include "client/io/str_cat.h"

namespace forestmap::client {
namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

constexpr size_t kSniffedBytes = 4096;  // the start of a file looked at for binary content

// Throws CsvError when `content` is no UTF-8 / ASCII text table, saying what it is instead.
void CheckIsText(const std::string& content, const std::string& name) {
  const auto starts = [&](std::string_view magic) { return content.rfind(magic, 0) == 0; };
  std::string what;
  if (starts("\xFF\xFE") || starts("\xFE\xFF")) {
    what = "UTF-16 text (Excel's \"Unicode text\"): save it as UTF-8 CSV (\"CSV UTF-8\")";
  } else if (starts("LASF")) {
    what = "a LAS point cloud, not a tree table: use `forestmap detect` to find its trees";
  } else if (starts("PK\x03\x04")) {
    what = "a zip archive (an .xlsx workbook?), not a text table: save the sheet as CSV";
  } else if (starts("\x7F"
                    "ELF")) {
    what = "an executable (ELF), not a text table";
  } else if (content.find('\0') < kSniffedBytes) {
    what = "binary data (a NUL byte near the start), not a text table";
  } else {
    return;
  }
  throw CsvError(name + ": " + what);
}

// The separator of the header line starting at `pos`: ';' or tab when there are more of them
// than commas outside quotes, else ','.
char DetectSeparator(const std::string& content, size_t pos) {
  size_t commas = 0, semicolons = 0, tabs = 0;
  bool quoted = false;
  for (; pos < content.size() && (quoted || content[pos] != '\n'); ++pos) {
    const char c = content[pos];
    if (c == '"') quoted = !quoted;
    if (quoted) continue;
    commas += c == ',';
    semicolons += c == ';';
    tabs += c == '\t';
  }
  if (semicolons > commas && semicolons >= tabs) return ';';
  if (tabs > commas && tabs > semicolons) return '\t';
  return ',';
}

// "12,5" (digits, one comma, digits; a sign allowed): a number with a decimal comma.
bool IsDecimalComma(std::string_view text) {
  if (!text.empty() && (text.front() == '-' || text.front() == '+')) text.remove_prefix(1);
  const size_t comma = text.find(',');
  if (comma == std::string_view::npos || comma == 0 || comma + 1 == text.size()) return false;
  for (size_t i = 0; i < text.size(); ++i) {
    if (i != comma && !std::isdigit(static_cast<unsigned char>(text[i]))) return false;
  }
  return true;
}

std::string ReadWholeFile(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw CsvError(path + ": is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CsvError(path + ": cannot open: " + std::strerror(errno));
  std::string content;
  // One read of the whole file when its size is known (regular files); else stream it.
  const uintmax_t size = std::filesystem::file_size(path, ec);
  if (!ec) {
    content.resize(size);
    in.read(content.data(), static_cast<std::streamsize>(size));
    content.resize(static_cast<size_t>(in.gcount()));
  } else {
    std::ostringstream buffer;
    buffer << in.rdbuf();
    content = std::move(buffer).str();
  }
  if (in.bad()) throw CsvError(path + ": read error: " + std::strerror(errno));
  return content;
}

}  // namespace

std::string ReadCsvFile(const std::string& path) { return ReadWholeFile(path); }

CsvReader CsvReader::Open(const std::string& path) { return CsvReader(ReadWholeFile(path), path); }

CsvReader::CsvReader(std::string content, std::string name)
    : content_(std::move(content)), name_(std::move(name)) {
  CheckIsText(content_, name_);
  if (content_.rfind("\xEF\xBB\xBF", 0) == 0) pos_ = 3;  // UTF-8 byte-order mark
  SkipBlankLines();
  separator_ = DetectSeparator(content_, pos_);
  if (!ParseRecord()) throw CsvError(name_ + ": empty file (no header)");
  header_line_ = record_line_;
  header_.reserve(fields_.size());
  for (const CsvField& field : fields_) header_.emplace_back(field.text);
}

bool CsvReader::Next() {
  if (!ParseRecord()) return false;
  if (fields_.size() != header_.size()) {
    Fail(std::to_string(fields_.size()) + " fields, header has " + std::to_string(header_.size()));
  }
  return true;
}

void CsvReader::FailAt(size_t column, const std::string& problem) const {
  const std::string column_name =
      column < header_.size() ? header_[column] : StrCat({"#", std::to_string(column + 1)});
  Fail("column '" + column_name + "': " + problem);
}

void CsvReader::Fail(const std::string& problem) const {
  throw CsvError(StrCat({name_, ":", std::to_string(record_line_), ": ", problem}));
}

bool CsvReader::SkipBlankLines() {
  const size_t n = content_.size();
  while (true) {
    size_t p = pos_;
    while (p < n && IsBlank(content_[p])) ++p;
    if (p >= n) {
      pos_ = p;
      return false;
    }
    if (content_[p] != '\n') return true;
    pos_ = p + 1;
    ++line_;
  }
}

bool CsvReader::ParseRecord() {
  fields_.clear();
  if (!SkipBlankLines()) return false;
  record_line_ = line_;
  const size_t n = content_.size();
  while (true) {
    while (pos_ < n && content_[pos_] != '\r' && IsTrimmed(content_[pos_])) ++pos_;
    const bool quoted = pos_ < n && content_[pos_] == '"';
    fields_.push_back(quoted ? ParseQuoted(fields_.size()) : ParseUnquoted());
    if (pos_ >= n) return true;
    if (content_[pos_] == separator_) {
      ++pos_;
      continue;
    }
    // The only other stop is the end of the line.
    ++pos_;
    ++line_;
    return true;
  }
}

CsvField CsvReader::ParseUnquoted() {
  const size_t n = content_.size();
  const size_t start = pos_;
  while (pos_ < n && content_[pos_] != separator_ && content_[pos_] != '\n') ++pos_;
  size_t end = pos_;
  while (end > start && IsTrimmed(content_[end - 1])) --end;
  const std::string_view text(content_.data() + start, end - start);
  if (separator_ == ';' && IsDecimalComma(text)) content_[start + text.find(',')] = '.';
  return {text, false};
}

CsvField CsvReader::ParseQuoted(size_t field_index) {
  const size_t n = content_.size();
  ++pos_;  // the opening quote
  const size_t start = pos_;
  size_t out = pos_;
  while (true) {
    if (pos_ >= n) FailAt(field_index, "unterminated quoted field");
    const char c = content_[pos_];
    if (c == '"') {
      if (pos_ + 1 < n && content_[pos_ + 1] == '"') {
        content_[out++] = '"';
        pos_ += 2;
        continue;
      }
      ++pos_;
      break;
    }
    if (c == '\n') ++line_;
    content_[out++] = c;
    ++pos_;
  }
  while (pos_ < n && IsTrimmed(content_[pos_])) ++pos_;
  if (pos_ < n && content_[pos_] != separator_ && content_[pos_] != '\n') {
    FailAt(field_index, "unexpected text after a closing quote");
  }
  return {std::string_view(content_.data() + start, out - start), true};
}

}  // namespace forestmap::client
