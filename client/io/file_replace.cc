#include "client/io/file_replace.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <filesystem>
#include <system_error>

#include "client/io/csv_reader.h"

namespace forestmap::client {
namespace {

namespace fs = std::filesystem;

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// The files in the directory of `path` named STEM + an extension in `extensions` (lower case).
std::vector<fs::path> Sidecars(const std::string& path,
                               const std::vector<std::string>& extensions) {
  const fs::path file(path);
  const fs::path directory = file.parent_path().empty() ? fs::path(".") : file.parent_path();
  const std::string stem = file.stem().string();
  std::vector<fs::path> found;
  std::error_code error;
  for (const fs::directory_entry& entry : fs::directory_iterator(directory, error)) {
    const fs::path& candidate = entry.path();
    if (candidate.stem().string() != stem || !entry.is_regular_file(error)) continue;
    const std::string extension = Lower(candidate.extension().string());
    if (std::find(extensions.begin(), extensions.end(), extension) != extensions.end()) {
      found.push_back(file.parent_path() / candidate.filename());
    }
  }
  std::sort(found.begin(), found.end());  // .PRJ before .prj: the same choice every time
  return found;
}

}  // namespace

std::string TemporaryBeside(const std::string& path) {
  static std::atomic<int> counter{0};
  const fs::path file(path);
  if (!file.parent_path().empty() && !fs::is_directory(file.parent_path())) {
    throw CsvError(path + ": cannot write: no directory " + file.parent_path().string());
  }
  std::string name = ".";  // appended piece by piece: GCC 12's -Wrestrict misfires on a + chain
  name += file.filename().string();
  name += ".tmp-";
  name += std::to_string(::getpid());
  name += "-";
  name += std::to_string(counter++);
  name += file.extension().string();
  return (file.parent_path() / name).string();
}

void MoveInto(const std::string& from, const std::string& to) {
  std::error_code error;
  fs::rename(from, to, error);
  if (error) throw CsvError(to + ": cannot put the written file in place: " + error.message());
}

void ReplaceFile(const std::string& path, const std::function<void(const std::string&)>& write) {
  if (fs::is_directory(path)) throw CsvError(path + ": is a directory");
  const std::string temporary = TemporaryBeside(path);
  try {
    write(temporary);
    MoveInto(temporary, path);
  } catch (...) {
    std::error_code ignored;
    fs::remove_all(temporary, ignored);
    throw;
  }
}

std::optional<std::string> FindSidecar(const std::string& path, const std::string& extension) {
  const std::vector<fs::path> found = Sidecars(path, {Lower(extension)});
  if (found.empty()) return std::nullopt;
  return found.back().string();  // .prj (lower case, sorted last) when both are there
}

std::vector<std::string> RemoveSidecars(const std::string& path,
                                        const std::vector<std::string>& extensions) {
  std::vector<std::string> removed;
  for (const fs::path& sidecar : Sidecars(path, extensions)) {
    std::error_code error;
    fs::remove(sidecar, error);
    if (error) throw CsvError(sidecar.string() + ": cannot remove: " + error.message());
    removed.push_back(sidecar.string());
  }
  return removed;
}

}  // namespace forestmap::client
