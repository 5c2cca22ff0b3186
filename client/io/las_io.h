#pragma once
// LAS 1.0-1.4 (uncompressed) reading, hand-written: Debian 12 ships no LAS library (libLAS and
// PDAL are heavy and PDAL is not in bookworm's default set). ASPRS LAS 1.4 R15 specification.

#include <string>

#include "client/io/scan_io_internal.h"

namespace forestmap::client {

// Coordinates are X*scale+offset in double. Intensity from every format; ring from an
// extra-bytes attribute named "ring" (any case). Throws ScanError "FILE: ...".
scan_io_internal::RawScan ReadLas(const std::string& path);

}  // namespace forestmap::client
