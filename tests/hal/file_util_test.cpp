// File and directory errors of hal/io/file_util: every failure reported as what it is (a readdir
// failure is not an empty directory, an fstat failure is not "not a regular file"), and sizes
// beyond what a 32-bit build can hold refused with a message instead of truncated.
#include "hal/io/file_util.hpp"

#include <catch2/catch.hpp>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tests/support/test_support.hpp"

namespace hal = epitrack::hal;

namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

void writeFrameFiles(const epitrack::test::TempDir& dir, int count) {
  std::string err;
  for (int i = 0; i < count; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "frame%03d.pgm", i);
    REQUIRE(hal::writeTextAtomic(dir.file(name), "P5 1 1 255\n\x7f", err));
  }
}

/// The unprivileged user the permission test runs as when the tests run as root (root reads any
/// directory whatever its mode).
constexpr uid_t kNobody = 65534;

/// Runs `body` in a child process as kNobody and returns what it wrote to its pipe; nullopt when
/// the child could not drop root's privileges (a container without that user mapping).
template <typename Body>
std::optional<std::string> runAsNobody(Body body) {
  int fds[2];
  if (::pipe(fds) != 0) return std::nullopt;
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    if (::setgid(kNobody) != 0 || ::setuid(kNobody) != 0) ::_exit(3);
    const std::string out = body();
    const ssize_t n = ::write(fds[1], out.data(), out.size());
    ::_exit(n == static_cast<ssize_t>(out.size()) ? 0 : 4);
  }
  ::close(fds[1]);
  std::string out;
  char chunk[256];
  for (ssize_t n; (n = ::read(fds[0], chunk, sizeof(chunk))) > 0;) {
    out.append(chunk, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  int status = 0;
  if (pid < 0 || ::waitpid(pid, &status, 0) != pid || !WIFEXITED(status) ||
      WEXITSTATUS(status) != 0) {
    return std::nullopt;
  }
  return out;
}

}  // namespace

TEST_CASE("A directory whose reading fails is an error naming readdir's errno, not 'no frames'",
          "[hal][files]") {
  // The failure 32-bit builds without large-file support met on ext4 (EOVERFLOW from readdir, then
  // reported as an empty directory). Here reading fails for real: the directory stream's
  // descriptor is replaced by one of /dev/null after opendir, so getdents fails with ENOTDIR.
  epitrack::test::TempDir dir("files-readdir");
  writeFrameFiles(dir, 3);
  DIR* stream = ::opendir(dir.path().c_str());
  REQUIRE(stream != nullptr);
  const int null_fd = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  REQUIRE(null_fd >= 0);
  REQUIRE(::dup2(null_fd, ::dirfd(stream)) == ::dirfd(stream));
  ::close(null_fd);
  std::vector<std::string> names;
  std::string err;
  const bool read = hal::readFrameNames(stream, dir.path(), names, err);
  ::closedir(stream);
  CHECK_FALSE(read);
  CHECK(contains(err, "cannot read directory '" + dir.path() + "'"));
  CHECK(contains(err, std::strerror(ENOTDIR)));
  CHECK_FALSE(contains(err, "no frames"));

  // The same directory, read normally: its three frames, sorted.
  std::vector<std::string> paths;
  REQUIRE(hal::listFrameFiles(dir.path(), paths, err));
  REQUIRE(paths.size() == 3);
  CHECK(paths[0] == dir.file("frame000.pgm"));
  CHECK(paths[2] == dir.file("frame002.pgm"));
}

TEST_CASE("Listing a file, a missing path or an empty directory says which", "[hal][files]") {
  epitrack::test::TempDir dir("files-list");
  std::string err;
  std::vector<std::string> paths;
  REQUIRE(hal::writeTextAtomic(dir.file("notes.txt"), "not a directory\n", err));
  CHECK_FALSE(hal::listFrameFiles(dir.file("notes.txt"), paths, err));
  CHECK(contains(err, "cannot open directory '" + dir.file("notes.txt") + "'"));
  CHECK(contains(err, std::strerror(ENOTDIR)));

  CHECK_FALSE(hal::listFrameFiles(dir.file("missing"), paths, err));
  CHECK(contains(err, std::strerror(ENOENT)));

  // Only files without a frame extension (and a hidden frame): no frames, said as such.
  REQUIRE(hal::writeTextAtomic(dir.file(".hidden.pgm"), "P5 1 1 255\n\x7f", err));
  CHECK_FALSE(hal::listFrameFiles(dir.path(), paths, err));
  CHECK(contains(err, "holds no frames"));
  CHECK(paths.empty());
}

TEST_CASE("A directory without read permission is a permission error", "[hal][files]") {
  // Root reads any directory: as root, the listing runs in a child process as an unprivileged
  // user. Checked before any assertion: whether that user can be switched to.
  const bool root = ::geteuid() == 0;
  if (root && !runAsNobody([] { return std::string("ok"); })) {
    std::printf("EPITRACK-SKIP: running as root and cannot switch to uid %u\n", kNobody);
    return;
  }
  epitrack::test::TempDir dir("files-perm");
  writeFrameFiles(dir, 2);
  // The temporary directory is 0700: open its path to others, then take read permission away.
  REQUIRE(::chmod(dir.path().c_str(), 0311) == 0);
  const auto list = [&dir] {
    std::vector<std::string> paths;
    std::string err;
    return hal::listFrameFiles(dir.path(), paths, err) ? std::string("listed") : err;
  };
  const std::string err = root ? runAsNobody(list).value_or("child failed") : list();
  REQUIRE(::chmod(dir.path().c_str(), 0700) == 0);  // so that TempDir can remove it
  CHECK(contains(err, "cannot open directory '" + dir.path() + "'"));
  CHECK(contains(err, std::strerror(EACCES)));
}

TEST_CASE("File size queries report fstat's errno, non-regular files and sizes beyond size_t",
          "[hal][files]") {
  std::size_t size = 0;
  std::string err;
  CHECK_FALSE(hal::regularFileSize(-1, "bad-fd", size, err));
  CHECK(contains(err, "cannot query 'bad-fd'"));
  CHECK(contains(err, std::strerror(EBADF)));

  epitrack::test::TempDir dir("files-size");
  std::vector<uint8_t> bytes;
  CHECK_FALSE(hal::readFileInto(dir.path(), bytes, err));
  CHECK(contains(err, "is not a regular file"));

  // A sparse file of 5 GB (no disk space used): off_t is 64-bit on every build, so its size is
  // known exactly; a 32-bit build refuses it instead of truncating 5 GB to 1 GB in size_t.
  constexpr int64_t kFiveGb = int64_t{5} << 30;
  const std::string big = dir.file("big.bin");
  const int fd = ::open(big.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  REQUIRE(fd >= 0);
  REQUIRE(::ftruncate(fd, static_cast<off_t>(kFiveGb)) == 0);
  const bool fits = hal::regularFileSize(fd, big, size, err);
  ::close(fd);
  if constexpr (sizeof(std::size_t) == 4) {
    CHECK_FALSE(fits);
    CHECK(contains(err, "too large for this 32-bit build (5368709120 bytes)"));
    CHECK_FALSE(hal::readFileInto(big, bytes, err));
    CHECK(contains(err, "too large"));
  } else {
    CHECK(fits);
    CHECK(static_cast<int64_t>(size) == kFiveGb);
  }
}
