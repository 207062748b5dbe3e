// Output files that cannot tear: every file ssiu writes goes through these functions. The data are
// written to a temporary beside the target, flushed, checked and fsync'ed, then renamed over the
// target, so a reader (or a later run) sees either the old file or the complete new one, never a
// half-written one, and a write error (disk full) is an InputError naming the file (exit 1).
// Targets that are not regular files (/dev/stdout, /dev/full, a pipe) cannot be renamed over: they
// are written directly and the stream is checked; "-" is stdout.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <string>

namespace ssiu {

// Writes `path` from `write`, which streams the whole content. If `write` throws (or the process
// dies) the old file is left intact and the temporary removed (when the process survives).
void WriteFileAtomic(const std::string& path, const std::function<void(std::ostream&)>& write);
void WriteFileAtomic(const std::string& path, const std::string& bytes);

// For writers that need a path of their own (cfitsio): `write(temp_path)` creates the file at
// temp_path (which keeps the target's extension), then it is checked and renamed to `path`.
void WriteFileViaTemp(const std::string& path, const std::function<void(const std::string& temp_path)>& write);

// CRC-32 (ISO 3309, as zlib and PNG) of a buffer, to tie a data file to its metadata.
uint32_t Crc32(const void* data, size_t bytes);

}  // namespace ssiu
