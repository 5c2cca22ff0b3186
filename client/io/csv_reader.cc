#include "client/io/csv_reader.h"

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

CsvReader CsvReader::Open(const std::string& path) { return CsvReader(ReadWholeFile(path), path); }

CsvReader::CsvReader(std::string content, std::string name)
    : content_(std::move(content)), name_(std::move(name)) {
  if (content_.rfind("\xEF\xBB\xBF", 0) == 0) pos_ = 3;  // UTF-8 byte-order mark
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
    while (pos_ < n && (content_[pos_] == ' ' || content_[pos_] == '\t')) ++pos_;
    const bool quoted = pos_ < n && content_[pos_] == '"';
    fields_.push_back(quoted ? ParseQuoted(fields_.size()) : ParseUnquoted());
    if (pos_ >= n) return true;
    if (content_[pos_] == ',') {
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
  while (pos_ < n && content_[pos_] != ',' && content_[pos_] != '\n') ++pos_;
  size_t end = pos_;
  while (end > start && IsBlank(content_[end - 1])) --end;
  return {std::string_view(content_.data() + start, end - start), false};
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
  while (pos_ < n && IsBlank(content_[pos_])) ++pos_;
  if (pos_ < n && content_[pos_] != ',' && content_[pos_] != '\n') {
    FailAt(field_index, "unexpected text after a closing quote");
  }
  return {std::string_view(content_.data() + start, out - start), true};
}

}  // namespace forestmap::client
