#pragma once
// Helpers shared by the tree file tests (tree_csv_test.cc, tree_columns_test.cc).

#include <string>

#include "client/io/tree_csv.h"

namespace forestmap::client::testing_util {

// The message of the CsvError thrown by `read`, or "" when nothing was thrown.
template <typename Read>
std::string CsvErrorOf(Read read) {
  try {
    read();
  } catch (const CsvError& error) {
    return error.what();
  }
  return "";
}

}  // namespace forestmap::client::testing_util
