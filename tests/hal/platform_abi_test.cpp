// The platform types the HAL relies on, checked on the target (the armhf stage runs this under
// qemu-arm): 64-bit file offsets and time on every build (cmake/EpitrackCompileOptions.cmake sets
// _FILE_OFFSET_BITS=64 and _TIME_BITS=64 on 32-bit targets), and a V4L2 buffer whose ioctl number
// encodes the layout the program uses.
#include <catch2/catch.hpp>

#include <ctime>

#include <linux/videodev2.h>
#include <sys/stat.h>
#include <sys/types.h>

TEST_CASE("File offsets, file sizes and time are 64-bit on every build", "[hal][abi]") {
  CHECK(sizeof(off_t) == 8);
  const struct stat st {};
  CHECK(sizeof(st.st_size) == 8);
  CHECK(sizeof(time_t) == 8);
  const timespec ts{};
  CHECK(sizeof(ts.tv_sec) == 8);
}

TEST_CASE("The V4L2 buffer ioctls carry the struct the program fills, with 64-bit timestamps",
          "[hal][abi][v4l2]") {
  // The kernel decodes the struct by the size in the ioctl number: on a 32-bit build with 64-bit
  // time that is the 80-byte time64 layout (Linux 5.6+), on 64-bit builds the native one.
  CHECK(_IOC_SIZE(VIDIOC_QBUF) == sizeof(v4l2_buffer));
  CHECK(_IOC_SIZE(VIDIOC_DQBUF) == sizeof(v4l2_buffer));
  CHECK(_IOC_SIZE(VIDIOC_QUERYBUF) == sizeof(v4l2_buffer));
  const v4l2_buffer buf{};
  CHECK(sizeof(buf.timestamp.tv_sec) == 8);
  if constexpr (sizeof(void*) == 4) {
    CHECK(sizeof(v4l2_buffer) == 80);
  } else {
    CHECK(sizeof(v4l2_buffer) == 88);
  }
}
