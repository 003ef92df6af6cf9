#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <dirent.h>

namespace epitrack::hal {

/// Reads a whole file into `bytes` (resized; capacity is kept, so reading frames of similar size
/// stops allocating after the first few). Returns false with a message naming the file.
bool readFileInto(const std::string& path, std::vector<uint8_t>& bytes, std::string& error);

/// Writes `size` bytes to `path` through a temporary file in the same directory that is renamed
/// over `path` only when complete, so an interrupted write never leaves a truncated file behind.
bool writeFileAtomic(const std::string& path, const void* data, std::size_t size,
                     std::string& error);

/// Atomic text write, see writeFileAtomic.
bool writeTextAtomic(const std::string& path, const std::string& text, std::string& error);

/// The size of the regular file open as `fd`. False with a message naming `path` when fstat fails
/// (its errno), the file is not a regular file, or it is too large for this build's memory
/// (over PTRDIFF_MAX bytes: 2 GB on 32-bit targets, where size_t is narrower than off_t).
bool regularFileSize(int fd, const std::string& path, std::size_t& size, std::string& error);

/// Lists the frame files of a directory (*.jpg, *.jpeg, *.png, *.pgm, *.ppm, any case), sorted
/// by name (byte order). Returns false with a message saying which when the directory cannot be
/// opened (its errno: missing, not a directory, permission), cannot be read (readdir's errno), or
/// holds no frames.
bool listFrameFiles(const std::string& dir, std::vector<std::string>& paths, std::string& error);

/// The frame file names of an open directory stream, unsorted (listFrameFiles' reading step).
/// False with readdir's errno in the message (naming `dir`) when reading fails part way: a failure
/// is never taken for the end of the directory.
bool readFrameNames(DIR* stream, const std::string& dir, std::vector<std::string>& names,
                    std::string& error);

/// True when `path` names an existing directory.
bool isDirectory(const std::string& path);

/// Creates `path` and its missing parents (like `mkdir -p`).
bool makeDirectories(const std::string& path, std::string& error);

/// The text of errno `err` ("No such file or directory").
std::string errnoText(int err);

}  // namespace epitrack::hal
