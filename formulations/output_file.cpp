#include "formulations/output_file.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

#include "solver/error.hpp"

namespace kneedyn {

namespace fs = std::filesystem;

namespace {

[[noreturn]] void Refuse(const std::string& function, const std::string& option, const std::string& path,
                         const std::string& rule) {
  Throw<InputError>(function.c_str(), option, " = '", EchoPath(path), "': ", rule);
}

// `where` (an existing directory) takes new entries: access() for the mode bits, and one
// probe directory made and removed, since access() passes for root wherever the mode bits
// allow while in /proc or /sys mkdir fails all the same.
void ProbeDirectory(const std::string& function, const std::string& option, const std::string& path,
                    const fs::path& where) {
  std::error_code ec;
  if (!fs::is_directory(where, ec)) {
    Refuse(function, option, path, "'" + EchoPath(where.string()) + "' is not a directory");
  }
  if (::access(where.c_str(), W_OK | X_OK) != 0) {
    Refuse(function, option, path, "cannot write in '" + EchoPath(where.string()) + "' (" + std::strerror(errno) + ")");
  }
  const fs::path probe = where / (".kneedyn-probe-" + std::to_string(::getpid()));
  if (::mkdir(probe.c_str(), 0700) != 0 && errno != EEXIST) {
    Refuse(function, option, path, "cannot create anything in '" + EchoPath(where.string()) + "' (" +
                                       std::strerror(errno) + ")");
  }
  ::rmdir(probe.c_str());
}

}  // namespace

fs::path NearestExistingAncestor(const fs::path& path) {
  std::error_code ec;
  fs::path ancestor = path.parent_path();
  for (;;) {
    if (ancestor.empty()) return ".";
    if (fs::exists(fs::symlink_status(ancestor, ec))) return ancestor;
    const fs::path up = ancestor.parent_path();
    if (up == ancestor) return ancestor;
    ancestor = up;
  }
}

void CheckOutputFile(const std::string& function, const std::string& option, const std::string& path) {
  if (path.empty()) Refuse(function, option, path, "must name a file");
  std::error_code ec;
  const fs::path file(path);
  if (fs::is_directory(file, ec)) Refuse(function, option, path, "is a directory; must name a file");
  // The write renames a new file over `path`: it replaces regular files only, never a device
  // (/dev/null, as root), a FIFO or a symbolic link (which would be replaced, not followed).
  const fs::file_status status = fs::symlink_status(file, ec);
  if (fs::is_symlink(status)) Refuse(function, option, path, "is a symbolic link; name the file itself");
  if (fs::exists(status) && !fs::is_regular_file(status)) {
    Refuse(function, option, path, "exists and is not a regular file (a device, FIFO or socket); must name a new or "
                                   "a regular file");
  }
  ProbeDirectory(function, option, path, NearestExistingAncestor(file));  // WriteOutputFile creates the levels below
}

void CheckOutputDirectoryWritable(const std::string& function, const std::string& option, const std::string& dir) {
  if (dir.empty()) Refuse(function, option, dir, "must name a directory");
  std::error_code ec;
  const fs::file_status status = fs::status(dir, ec);
  if (fs::exists(status) && !fs::is_directory(status)) Refuse(function, option, dir, "exists and is not a directory");
  ProbeDirectory(function, option, dir, fs::exists(status) ? fs::path(dir) : NearestExistingAncestor(fs::path(dir)));
}

void WriteOutputFile(const std::string& function, const std::string& option, const std::string& path,
                     const std::string& text) {
  CheckOutputFile(function, option, path);
  const fs::path file(path);
  std::error_code ec;
  if (file.has_parent_path()) {
    fs::create_directories(file.parent_path(), ec);
    if (ec) Refuse(function, option, path, "cannot create its directory (" + ec.message() + ")");
  }
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary);
    out << text;
    out.close();
    if (!out) {
      const std::string reason = std::strerror(errno);
      fs::remove(tmp, ec);
      Refuse(function, option, path, "cannot be written (" + reason + ")");
    }
  }
  fs::rename(tmp, file, ec);
  if (ec) {
    const std::string reason = ec.message();
    fs::remove(tmp, ec);
    Refuse(function, option, path, "cannot replace it by '" + EchoPath(tmp) + "' (" + reason + ")");
  }
}

}  // namespace kneedyn
