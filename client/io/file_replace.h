#pragma once
// Writing a file so that it appears whole or not at all: write to a temporary path beside it (same
// directory, so a rename is atomic), then rename into place. And the sidecar files GIS tools keep
// beside a file (FILE.prj, FILE.PRJ), found whatever the case of their extension.
//
// Errors are CsvError naming the file.

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace forestmap::client {

// A path in the directory of `path` that no one else uses: ".NAME.tmp-PID-N" plus `path`'s
// extension (GDAL drivers look at it). Throws CsvError when the directory does not exist.
std::string TemporaryBeside(const std::string& path);

// Calls write(temporary) and renames the temporary file to `path` when it returns; when it
// throws, removes what it wrote (file or directory) and rethrows: `path` is left as it was.
void ReplaceFile(const std::string& path, const std::function<void(const std::string&)>& write);

// Renames `from` to `to`, replacing `to`.
void MoveInto(const std::string& from, const std::string& to);

// The file beside `path` with its stem and `extension` (".prj"), in any case (.prj, .PRJ).
std::optional<std::string> FindSidecar(const std::string& path, const std::string& extension);

// Removes every file beside `path` with its stem and one of `extensions`, in any case; returns
// what it removed.
std::vector<std::string> RemoveSidecars(const std::string& path,
                                        const std::vector<std::string>& extensions);

}  // namespace forestmap::client
