#include "hal/v4l2/v4l2_syscalls.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

namespace epitrack::hal {
namespace {

class LinuxV4l2Syscalls final : public V4l2Syscalls {
 public:
  int open(const char* path, int flags) override { return ::open(path, flags); }
  int close(int fd) override { return ::close(fd); }
  int ioctl(int fd, unsigned long request, void* arg) override { return ::ioctl(fd, request, arg); }
  void* mmap(void* addr, std::size_t length, int prot, int flags, int fd, off_t offset) override {
    return ::mmap(addr, length, prot, flags, fd, offset);
  }
  int munmap(void* addr, std::size_t length) override { return ::munmap(addr, length); }
  int poll(struct pollfd* fds, nfds_t count, int timeout_ms) override {
    return ::poll(fds, count, timeout_ms);
  }
};

}  // namespace

V4l2Syscalls& linuxV4l2Syscalls() {
  static LinuxV4l2Syscalls instance;
  return instance;
}

}  // namespace epitrack::hal
