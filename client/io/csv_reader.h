#pragma once
// A small, fast reader of comma-separated files as written by R, pandas and spreadsheets.
//
// Why hand-written: the per-frame detection files have ~320k lines and must parse in well under
// a second; Debian ships no C++ CSV library. The dialect (RFC 4180 plus what R's write.csv does):
// - a header row names the columns; the first non-blank line is the header;
// - fields are separated by ',', or by ';' or tab when the header has more of those than commas
//   (European spreadsheets, tab-separated text); spaces (and tabs, unless they separate) around a
//   field are trimmed;
// - in a ';' file, an unquoted field of digits with one decimal comma (0,149) reads as 0.149;
// - a field may be quoted with '"', inside which the separator and newlines are literal and '""'
//   is a '"';
// - lines end with "\n" or "\r\n"; blank lines are skipped; a UTF-8 byte-order mark is ignored.
// UTF-16 text (a byte-order mark FF FE or FE FF) and binary files (zip / .xlsx, ELF, LAS, or any
// NUL byte near the start) are refused with a message saying what the file is.
// Whether a field was quoted is reported, because R writes a missing string as unquoted NA and
// the string "NA" quoted.

#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace forestmap::client {

// Every error of reading or writing a tree file. The message names the file and, where there is
// one, the line and the column: "FILE:LINE: column 'NAME': problem".
class CsvError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct CsvField {
  std::string_view text;  // trimmed and unescaped; valid until the next call of Next()
  bool quoted = false;
};

class CsvReader {
 public:
  // Reads the whole file into memory and parses its header. Throws CsvError when the file cannot
  // be read or has no header ("FILE: empty file (no header)").
  static CsvReader Open(const std::string& path);

  // As Open, for text already in memory; `name` stands for the file name in messages.
  CsvReader(std::string content, std::string name);

  const std::string& name() const { return name_; }
  char separator() const { return separator_; }
  // Column names as written (trimmed, unquoted).
  const std::vector<std::string>& header() const { return header_; }
  int header_line() const { return header_line_; }

  // Advances to the next record; false at the end of the file. Throws CsvError for a record
  // whose field count differs from the header's, or for an unterminated quote.
  bool Next();
  const std::vector<CsvField>& fields() const { return fields_; }
  // The line on which the current record starts (1-based).
  int line() const { return record_line_; }

  // Throws CsvError "NAME:LINE: column 'HEADER[column]': problem" for the current record.
  [[noreturn]] void FailAt(size_t column, const std::string& problem) const;
  // Throws CsvError "NAME:LINE: problem" for the current record.
  [[noreturn]] void Fail(const std::string& problem) const;

 private:
  // Parses one record starting at pos_ into fields_; false at the end of input.
  bool ParseRecord();
  bool SkipBlankLines();
  CsvField ParseQuoted(size_t field_index);
  CsvField ParseUnquoted();
  bool IsTrimmed(char c) const { return (c == ' ' || c == '\t' || c == '\r') && c != separator_; }

  std::string content_;  // unescaped in place: an unescaped field is never longer than its text
  std::string name_;
  std::vector<std::string> header_;
  int header_line_ = 0;
  std::vector<CsvField> fields_;
  size_t pos_ = 0;
  int line_ = 1;  // line of pos_
  int record_line_ = 0;
  char separator_ = ',';
};

// The whole file, as CsvReader::Open reads it. Throws CsvError when it cannot be read.
std::string ReadCsvFile(const std::string& path);

}  // namespace forestmap::client
