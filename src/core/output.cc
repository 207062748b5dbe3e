#include "core/output.h"

#include <fcntl.h>
#include <libdeflate.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "core/error.h"

namespace ssiu {
namespace {

namespace fs = std::filesystem;

// A regular-file target (or one that does not exist yet) is written via a temporary; anything else
// (a device, a pipe) directly. A symlink is followed so that the link stays a link.
bool ResolveTarget(const std::string& path, std::string* target) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!ec && fs::exists(st) && !fs::is_regular_file(st)) {
    if (fs::is_directory(st)) throw InputError(path, "is a directory, cannot write a file there");
    return false;
  }
  *target = path;
  if (fs::is_symlink(fs::symlink_status(path, ec))) {
    const fs::path resolved = fs::weakly_canonical(path, ec);
    if (!ec) *target = resolved.string();
  }
  return true;
}

// A hidden name in the target's directory, unique per process and call, ending with the target's
// own name so that writers choosing the format by extension still see it.
std::string TempPathFor(const std::string& target) {
  static std::atomic<unsigned> counter{0};
  const fs::path p(target);
  std::ostringstream name;
  name << ".tmp-" << ::getpid() << "-" << counter++ << "-" << p.filename().string();
  return (p.parent_path() / name.str()).string();
}

std::string Errno() { return std::strerror(errno); }

// Flushes the temporary to the disk (so that a crash after the rename cannot leave an empty file),
// then renames it over the target.
void SyncAndRename(const std::string& temp, const std::string& target, const std::string& path) {
  const int fd = ::open(temp.c_str(), O_RDONLY);
  if (fd < 0 || ::fsync(fd) != 0) {
    const std::string why = Errno();
    if (fd >= 0) ::close(fd);
    throw InputError(path, "write failed (" + why + ")");
  }
  ::close(fd);
  if (std::rename(temp.c_str(), target.c_str()) != 0) throw InputError(path, "cannot replace file (" + Errno() + ")");
}

// Removes the temporary unless it was renamed.
struct TempGuard {
  std::string path;
  bool keep = false;
  ~TempGuard() {
    if (!keep) std::remove(path.c_str());
  }
};

}  // namespace

void WriteFileAtomic(const std::string& path, const std::function<void(std::ostream&)>& write) {
  if (path.empty()) throw InputError("output", "empty file name");
  if (path == "-") {
    write(std::cout);
    std::cout.flush();
    if (!std::cout) throw InputError("stdout", "write failed");
    return;
  }
  std::string target;
  if (!ResolveTarget(path, &target)) {
    std::ofstream out(path, std::ios::binary);
    if (!out) throw InputError(path, "cannot write file");
    write(out);
    out.flush();
    if (!out) throw InputError(path, "write failed");
    out.close();
    if (!out) throw InputError(path, "write failed");
    return;
  }
  TempGuard temp{TempPathFor(target)};
  {
    std::ofstream out(temp.path, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError(path, "cannot write file (" + Errno() + ")");
    write(out);
    out.flush();
    if (!out) throw InputError(path, "write failed");
    out.close();
    if (!out) throw InputError(path, "write failed");
  }
  SyncAndRename(temp.path, target, path);
  temp.keep = true;
}

void WriteFileAtomic(const std::string& path, const std::string& bytes) {
  WriteFileAtomic(path,
                  [&](std::ostream& out) { out.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); });
}

void WriteFileViaTemp(const std::string& path, const std::function<void(const std::string& temp_path)>& write) {
  if (path.empty() || path == "-") throw InputError(path.empty() ? "output" : "stdout", "needs a file name");
  std::string target;
  if (!ResolveTarget(path, &target)) {
    // Written elsewhere first, then copied to the device and checked.
    const std::string temp = TempPathFor((fs::temp_directory_path() / fs::path(path).filename()).string());
    TempGuard guard{temp};
    write(temp);
    std::ifstream in(temp, std::ios::binary);
    if (!in) throw InputError(path, "write failed");
    WriteFileAtomic(path, [&](std::ostream& out) { out << in.rdbuf(); });
    return;
  }
  TempGuard temp{TempPathFor(target)};
  write(temp.path);
  std::error_code ec;
  if (!fs::is_regular_file(temp.path, ec)) throw InputError(path, "write failed (no file was created)");
  SyncAndRename(temp.path, target, path);
  temp.keep = true;
}

uint32_t Crc32(const void* data, size_t bytes) { return libdeflate_crc32(0, data, bytes); }

}  // namespace ssiu
