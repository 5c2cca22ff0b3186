// Room reserved on the database's file system for the writes that free room (storage/sqlite/
// internal.h, ReservedRoom): a file of real, allocated blocks next to the database, given back to
// the file system when such a write finds the disk full.

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <string>
#include <system_error>
#include <utility>

#include "storage/sqlite/internal.h"

namespace forestmap::storage::sqlite {

ReservedRoom::ReservedRoom(std::string path, int64_t bytes)
    : path_(std::move(path)), bytes_(bytes) {}

bool ReservedRoom::Hold() {
  if (bytes_ <= 0) return false;
  const int fd = open(path_.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) return false;
  // posix_fallocate allocates blocks (a sparse file would hold no room), MiB by MiB so that a
  // file system with less room than asked keeps what it has: part of the room is still room.
  constexpr int64_t kStep = 1 << 20;
  bool whole = true;
  for (int64_t offset = 0; offset < bytes_ && whole; offset += kStep) {
    whole = posix_fallocate(fd, offset, std::min(kStep, bytes_ - offset)) == 0;
  }
  close(fd);
  return whole;
}

bool ReservedRoom::Release() {
  std::error_code error;
  const uintmax_t size = std::filesystem::file_size(path_, error);
  if (error || size == 0) return false;  // no room held: nothing to give back
  return std::filesystem::remove(path_, error) && !error;
}

}  // namespace forestmap::storage::sqlite
