#include "hal/io/file_util.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace epitrack::hal {

std::string errnoText(int err) { return std::strerror(err); }

bool regularFileSize(int fd, const std::string& path, std::size_t& size, std::string& error) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    error = "cannot query '" + path + "': " + errnoText(errno);
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    error = "'" + path + "' is not a regular file";
    return false;
  }
  // off_t is 64-bit everywhere (cmake/EpitrackCompileOptions.cmake), size_t only 32-bit on 32-bit
  // targets; a buffer or mapping holds at most PTRDIFF_MAX bytes (2 GB there).
  if (st.st_size < 0 ||
      static_cast<std::uintmax_t>(st.st_size) >
          static_cast<std::uintmax_t>(std::numeric_limits<std::ptrdiff_t>::max())) {
    error = "'" + path + "' is too large for this " + std::to_string(sizeof(void*) * 8) +
            "-bit build (" + std::to_string(st.st_size) + " bytes)";
    return false;
  }
  size = static_cast<std::size_t>(st.st_size);
  return true;
}

bool readFileInto(const std::string& path, std::vector<uint8_t>& bytes, std::string& error) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    error = "cannot open '" + path + "': " + errnoText(errno);
    return false;
  }
  std::size_t size = 0;
  if (!regularFileSize(fd, path, size, error)) {
    ::close(fd);
    return false;
  }
  bytes.resize(size);
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error =
          "cannot read '" + path + "': " + (n < 0 ? errnoText(errno) : std::string("file shrank"));
      ::close(fd);
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
  return true;
}

bool writeFileAtomic(const std::string& path, const void* data, std::size_t size,
                     std::string& error) {
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    error = "cannot create '" + tmp + "': " + errnoText(errno);
    return false;
  }
  const auto* p = static_cast<const uint8_t*>(data);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, p + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      error = "cannot write '" + tmp + "': " + errnoText(errno);
      ::close(fd);
      ::unlink(tmp.c_str());
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) {
    error = "cannot write '" + tmp + "': " + errnoText(errno);
    ::unlink(tmp.c_str());
    return false;
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    error = "cannot rename '" + tmp + "' to '" + path + "': " + errnoText(errno);
    ::unlink(tmp.c_str());
    return false;
  }
  return true;
}

bool writeTextAtomic(const std::string& path, const std::string& text, std::string& error) {
  return writeFileAtomic(path, text.data(), text.size(), error);
}

namespace {
bool hasFrameExtension(const std::string& name) {
  const auto dot = name.rfind('.');
  if (dot == std::string::npos) return false;
  std::string ext = name.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == "jpg" || ext == "jpeg" || ext == "png" || ext == "pgm" || ext == "ppm";
}
}  // namespace

bool readFrameNames(DIR* stream, const std::string& dir, std::vector<std::string>& names,
                    std::string& error) {
  names.clear();
  for (;;) {
    // readdir returns null both at the end and on an error; only errno tells them apart.
    errno = 0;
    const dirent* e = ::readdir(stream);
    if (e == nullptr) {
      if (errno != 0) {
        error = "cannot read directory '" + dir + "': " + errnoText(errno);
        return false;
      }
      return true;
    }
    const std::string name = e->d_name;
    if (name.empty() || name[0] == '.' || !hasFrameExtension(name)) continue;
    names.push_back(name);
  }
}

bool listFrameFiles(const std::string& dir, std::vector<std::string>& paths, std::string& error) {
  paths.clear();
  DIR* stream = ::opendir(dir.c_str());
  if (stream == nullptr) {
    error = "cannot open directory '" + dir + "': " + errnoText(errno);
    return false;
  }
  std::vector<std::string> names;
  const bool read = readFrameNames(stream, dir, names, error);
  ::closedir(stream);
  if (!read) return false;
  if (names.empty()) {
    error = "directory '" + dir + "' holds no frames (*.jpg, *.jpeg, *.png, *.pgm, *.ppm)";
    return false;
  }
  std::sort(names.begin(), names.end());
  const std::string prefix = (!dir.empty() && dir.back() == '/') ? dir : dir + "/";
  for (const auto& n : names) paths.push_back(prefix + n);
  return true;
}

bool isDirectory(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

bool makeDirectories(const std::string& path, std::string& error) {
  if (path.empty()) return true;
  std::string partial;
  std::size_t pos = 0;
  while (pos != std::string::npos) {
    pos = path.find('/', pos + 1);
    partial = path.substr(0, pos);
    if (partial.empty()) continue;
    if (::mkdir(partial.c_str(), 0755) != 0 && errno != EEXIST) {
      error = "cannot create directory '" + partial + "': " + errnoText(errno);
      return false;
    }
  }
  if (!isDirectory(path)) {
    error = "'" + path + "' exists and is not a directory";
    return false;
  }
  return true;
}

}  // namespace epitrack::hal
