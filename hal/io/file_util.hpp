#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

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

/// Lists the frame files of a directory (*.jpg, *.jpeg, *.png, *.pgm, *.ppm, any case), sorted
/// by name (byte order). Returns false when the directory cannot be read or holds no frames.
bool listFrameFiles(const std::string& dir, std::vector<std::string>& paths, std::string& error);

/// True when `path` names an existing directory.
bool isDirectory(const std::string& path);

/// Creates `path` and its missing parents (like `mkdir -p`).
bool makeDirectories(const std::string& path, std::string& error);

/// The text of errno `err` ("No such file or directory").
std::string errnoText(int err);

}  // namespace epitrack::hal
