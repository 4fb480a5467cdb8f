#include "solver/plugin_loader.hpp"

#include <dlfcn.h>
#include <link.h>

#ifndef KNEEDYN_PLUGIN_LIBDIR
#define KNEEDYN_PLUGIN_LIBDIR "lib"
#endif

namespace kneedyn {

namespace fs = std::filesystem;

std::vector<fs::path> RunTimeCandidates(const fs::path& relative, const void* anchor) {
  std::vector<fs::path> origins;
  std::error_code ec;
  const fs::path exe = fs::weakly_canonical(fs::read_symlink("/proc/self/exe", ec), ec);
  Dl_info info{};
  if (anchor && dladdr(anchor, &info) != 0 && info.dli_fname && info.dli_fname[0] == '/') {
    std::error_code ec2;
    const fs::path object = fs::weakly_canonical(fs::path(info.dli_fname), ec2);
    if (!ec2 && object != exe) origins.push_back(object.parent_path());
  }
  if (!exe.empty()) origins.push_back(exe.parent_path());
  std::vector<fs::path> out;
  for (fs::path dir : origins) {
    for (int up = 0; up < 5 && !dir.empty(); ++up, dir = dir.parent_path()) {
      out.push_back(dir / relative);
      if (dir == dir.root_path()) break;
    }
  }
  return out;
}

std::vector<fs::path> PluginCandidates(const char* file_name, const void* anchor) {
  return RunTimeCandidates(fs::path(KNEEDYN_PLUGIN_LIBDIR) / "kneedyn" / file_name, anchor);
}

OpenedPlugin OpenPlugin(const char* file_name, const void* anchor, int dlopen_flags) {
  OpenedPlugin opened;
  for (const fs::path& candidate : PluginCandidates(file_name, anchor)) {
    std::error_code ec;
    if (!fs::is_regular_file(candidate, ec)) {
      opened.tried += (opened.tried.empty() ? "'" : ", '") + candidate.string() + "'";
      continue;
    }
    opened.path = candidate;
    opened.handle = dlopen(candidate.c_str(), dlopen_flags);
    if (!opened.handle) {
      const char* why = dlerror();
      opened.dlopen_error = why ? why : "unknown dlopen error";
    }
    return opened;
  }
  // A bare name: LD_LIBRARY_PATH and the run path of the object calling dlopen (here the
  // program, which holds the static libkneedyn_solver.a).
  if (void* handle = dlopen(file_name, dlopen_flags)) {
    link_map* map = nullptr;
    if (dlinfo(handle, RTLD_DI_LINKMAP, &map) == 0 && map && map->l_name) opened.path = map->l_name;
    if (opened.path.empty()) opened.path = file_name;
    opened.handle = handle;
  } else {
    dlerror();  // not found there either
    opened.tried += std::string(opened.tried.empty() ? "" : ", then ") + "'" + file_name +
                    "' on the dynamic linker's search path (LD_LIBRARY_PATH, the program's run path: kneedyn's "
                    "CMake package and kneedyn.pc put <prefix>/<libdir>/kneedyn on it)";
  }
  return opened;
}

}  // namespace kneedyn
