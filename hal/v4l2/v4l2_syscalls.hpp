#pragma once

#include <cstddef>

#include <poll.h>
#include <sys/types.h>

namespace epitrack::hal {

/// The syscall seam of V4L2 capture: the only way the capture code reaches the kernel. Each call
/// behaves like its Linux namesake, including returning -1 with `errno` set (MAP_FAILED for mmap).
/// Production uses `linuxV4l2Syscalls()`; the tests substitute a fake V4L2 driver, so the capture
/// code under test is the production code (libcamera's V4L2Device wraps ioctl the same way).
class V4l2Syscalls {
 public:
  V4l2Syscalls() = default;
  V4l2Syscalls(const V4l2Syscalls&) = delete;
  V4l2Syscalls& operator=(const V4l2Syscalls&) = delete;
  virtual ~V4l2Syscalls() = default;

  virtual int open(const char* path, int flags) = 0;
  virtual int close(int fd) = 0;
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;
  virtual void* mmap(void* addr, std::size_t length, int prot, int flags, int fd, off_t offset) = 0;
  virtual int munmap(void* addr, std::size_t length) = 0;
  virtual int poll(struct pollfd* fds, nfds_t count, int timeout_ms) = 0;
};

/// The real Linux calls (stateless; one shared instance).
V4l2Syscalls& linuxV4l2Syscalls();

}  // namespace epitrack::hal
