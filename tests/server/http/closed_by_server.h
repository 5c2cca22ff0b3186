#pragma once
// Whether the server has let go of a test's connection that is waiting for it.

#include <sys/socket.h>

#include <cerrno>

namespace forestmap::test {

// True once the server closed `sock` or wrote to it (end of stream, a reset, an alert, an
// answer); false while it holds the connection silently. Reads at most one byte.
inline bool ClosedByServer(int sock) {
  char byte = 0;
  const ssize_t got = recv(sock, &byte, 1, MSG_DONTWAIT);
  return got >= 0 || (errno != EAGAIN && errno != EWOULDBLOCK);
}

}  // namespace forestmap::test
