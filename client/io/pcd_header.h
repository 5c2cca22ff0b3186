#pragma once
// The header of a PCD file, read and checked by hand before PCL reads the points
// (client/io/pcd_io.cc): PCL reports problems by printing them and returning -1, and we want
// errors that name the field and the place. No PCL here.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace forestmap::client::pcd_internal {

struct PcdHeader {
  std::vector<std::string> fields;
  std::vector<int> sizes;
  std::vector<char> types;
  std::vector<int> counts;
  uint64_t width = 0;
  uint64_t height = 1;
  uint64_t points = 0;
  bool has_width = false;
  bool has_points = false;
  std::string data;          // ascii, binary or binary_compressed
  uint64_t data_offset = 0;  // bytes from the file start to the first data byte
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // from an "offset subtracted:" comment
};

// Parses the header (PCL skips comments, and we want the offset comment and our own messages).
// Throws the scan reader's error naming FILE:LINE and the field.
PcdHeader ReadHeader(const std::string& path);
// Checks that the data after the header can hold what the header promises before PCL allocates
// or maps it (ascii values, binary bytes, binary_compressed size words).
void CheckDataLength(const PcdHeader& h, const std::string& path);

}  // namespace forestmap::client::pcd_internal
