// vivid-loop: plays a raw 8-bit gray clip into vivid's video output device with vivid's video loop
// on, so that its capture device delivers the clip's frames through the kernel
// (tools/vm/checks.sh).
//   vivid-loop CAPTURE_DEV OUTPUT_DEV WIDTH HEIGHT CLIP.gray FRAMES GO_FILE [HOLD [PROGRESS]]
// CLIP.gray holds FRAMES frames of WIDTH x HEIGHT bytes. The first frame is shown until GO_FILE
// exists (at most 60 s: the capture has started), then the clip runs, each frame queued HOLD
// times (default 1). With PROGRESS, the pose file of a consumer writing one line per processed
// frame (epitrack-device --poses), a clip frame is held further until that file has grown by
// three lines after the HOLD periods: the first may be a frame processed from before, the next
// are from frames captured after this one was on show (the consumer drops stale frames), so a
// consumer of any speed (the tracker under emulation) processes every clip frame at least once.
// Two lines were not enough in 2 of 5 runs on an overloaded host (a clip frame skipped): the
// third is margin for a consumer that still got a frame from before.
// A consumer that stops writing holds a frame at most 60 s. The capture's input must be
// chosen before anyone streams from it, hence the wait instead of starting after the capture. vivid
// loops output to capture only between like connectors with the same format, field order and size:
// both are switched to S-Video, GREY, the same field order, and its on-screen text is turned off
// (it would change the pixels). Exit: 0 played, 1 a device refused something (the message says
// what), 2 bad arguments.
#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

enum { kBuffers = 4 };

static int xioctl(int fd, unsigned long request, void* arg) {
  int rc;
  do rc = ioctl(fd, request, arg);
  while (rc < 0 && errno == EINTR);
  return rc;
}

static int fail(const char* what) {
  fprintf(stderr, "vivid-loop: %s: %s\n", what, strerror(errno));
  return 1;
}

// Sets the control named NAME (as vivid names it) on FD; 0 when done.
static int setControlByName(int fd, const char* name, int value) {
  struct v4l2_queryctrl q;
  memset(&q, 0, sizeof(q));
  q.id = V4L2_CTRL_FLAG_NEXT_CTRL;
  while (xioctl(fd, VIDIOC_QUERYCTRL, &q) == 0) {
    if (strcmp((const char*)q.name, name) == 0) {
      struct v4l2_control c = {.id = q.id, .value = value};
      return xioctl(fd, VIDIOC_S_CTRL, &c);
    }
    q.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
  }
  errno = ENOENT;
  return -1;
}

// Sets GREY WIDTH x HEIGHT with FIELD on FD; the driver may choose another field order (S-Video is
// interlaced), which is returned in OUT and must then be used for the other side as well.
static int setFormat(int fd, enum v4l2_buf_type type, int width, int height, unsigned field,
                     struct v4l2_pix_format* out) {
  struct v4l2_format f;
  memset(&f, 0, sizeof(f));
  f.type = type;
  f.fmt.pix.width = (unsigned)width;
  f.fmt.pix.height = (unsigned)height;
  f.fmt.pix.pixelformat = V4L2_PIX_FMT_GREY;
  f.fmt.pix.field = field;
  if (xioctl(fd, VIDIOC_S_FMT, &f) < 0) return -1;
  *out = f.fmt.pix;
  const char* side = type == V4L2_BUF_TYPE_VIDEO_OUTPUT ? "output" : "capture";
  fprintf(stderr, "vivid-loop: %s format %ux%u fourcc %08x field %u bytesperline %u\n", side,
          out->width, out->height, out->pixelformat, out->field, out->bytesperline);
  if (out->width != (unsigned)width || out->height != (unsigned)height ||
      out->pixelformat != V4L2_PIX_FMT_GREY) {
    fprintf(stderr, "vivid-loop: the %s format is not %dx%d GREY\n", side, width, height);
    errno = EINVAL;
    return -1;
  }
  return 0;
}

// Selects the first input (or output) whose name contains "S-Video".
static int selectSvideo(int fd, int output) {
  for (unsigned i = 0; i < 16; ++i) {
    char name[32];
    if (output) {
      struct v4l2_output o = {.index = i};
      if (xioctl(fd, VIDIOC_ENUMOUTPUT, &o) < 0) break;
      memcpy(name, o.name, sizeof(name));
    } else {
      struct v4l2_input in = {.index = i};
      if (xioctl(fd, VIDIOC_ENUMINPUT, &in) < 0) break;
      memcpy(name, in.name, sizeof(name));
    }
    name[sizeof(name) - 1] = 0;
    if (strstr(name, "S-Video") != NULL) {
      int index = (int)i;
      return xioctl(fd, output ? VIDIOC_S_OUTPUT : VIDIOC_S_INPUT, &index);
    }
  }
  errno = ENOENT;
  return -1;
}

// Lines (newlines) in PATH so far, read incrementally (the file only grows); 0 while it is absent.
static long countLines(const char* path) {
  static long lines = 0;
  static off_t offset = 0;
  const int fd = open(path, O_RDONLY);
  if (fd < 0) return lines;
  char buffer[4096];
  ssize_t n;
  while ((n = pread(fd, buffer, sizeof(buffer), offset)) > 0) {
    for (ssize_t i = 0; i < n; ++i) lines += buffer[i] == '\n';
    offset += n;
  }
  close(fd);
  return lines;
}

int main(int argc, char** argv) {
  if (argc < 8 || argc > 10) {
    fprintf(stderr,
            "usage: vivid-loop CAPTURE_DEV OUTPUT_DEV WIDTH HEIGHT CLIP.gray FRAMES GO_FILE "
            "[HOLD [PROGRESS]]\n");
    return 2;
  }
  const char* progress = argc == 10 ? argv[9] : NULL;
  const int width = atoi(argv[3]), height = atoi(argv[4]), frames = atoi(argv[6]);
  const char* go_file = argv[7];
  const int hold = argc == 9 ? atoi(argv[8]) : 1;
  if (width <= 0 || height <= 0 || frames <= 0 || hold <= 0 || hold > 1000) {
    fprintf(stderr, "vivid-loop: bad size, frame count or hold\n");
    return 2;
  }
  const size_t frame_bytes = (size_t)width * (size_t)height;
  unsigned char* clip = malloc(frame_bytes * (size_t)frames);
  FILE* in = fopen(argv[5], "rb");
  if (clip == NULL || in == NULL ||
      fread(clip, frame_bytes, (size_t)frames, in) != (size_t)frames) {
    fprintf(stderr, "vivid-loop: cannot read %d frames of %dx%d from %s\n", frames, width, height,
            argv[5]);
    return 2;
  }
  fclose(in);

  const int cap = open(argv[1], O_RDWR);
  const int out = open(argv[2], O_RDWR);
  if (cap < 0 || out < 0) return fail("open");
  struct v4l2_pix_format cap_fmt, out_fmt;
  if (selectSvideo(cap, 0) < 0) return fail("capture S-Video input");
  if (selectSvideo(out, 1) < 0) return fail("output S-Video output");
  if (setFormat(cap, V4L2_BUF_TYPE_VIDEO_CAPTURE, width, height, V4L2_FIELD_NONE, &cap_fmt) < 0)
    return fail("capture format");
  if (setFormat(out, V4L2_BUF_TYPE_VIDEO_OUTPUT, width, height, cap_fmt.field, &out_fmt) < 0)
    return fail("output format");
  if (out_fmt.field != cap_fmt.field) {
    fprintf(stderr, "vivid-loop: output field order %u differs from the capture's %u\n",
            out_fmt.field, cap_fmt.field);
    return 1;
  }
  if (setControlByName(cap, "OSD Text Mode", 2) < 0) return fail("control 'OSD Text Mode'");
  if (setControlByName(cap, "Loop Video", 1) < 0) return fail("control 'Loop Video'");
  close(cap);  // the settings stay with the device

  struct v4l2_requestbuffers req = {
      .count = kBuffers, .type = V4L2_BUF_TYPE_VIDEO_OUTPUT, .memory = V4L2_MEMORY_MMAP};
  if (xioctl(out, VIDIOC_REQBUFS, &req) < 0 || req.count < 2) return fail("output buffers");
  unsigned char* mem[kBuffers];
  size_t length[kBuffers];
  for (unsigned i = 0; i < req.count && i < kBuffers; ++i) {
    struct v4l2_buffer b = {
        .index = i, .type = V4L2_BUF_TYPE_VIDEO_OUTPUT, .memory = V4L2_MEMORY_MMAP};
    if (xioctl(out, VIDIOC_QUERYBUF, &b) < 0) return fail("QUERYBUF");
    mem[i] = mmap(NULL, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, out, b.m.offset);
    if (mem[i] == MAP_FAILED) return fail("mmap");
    length[i] = b.length;
  }
  const unsigned buffers = req.count < kBuffers ? req.count : kBuffers;
  int streaming = 0;
  int lead = 0;             // periods frame 0 was shown before GO_FILE appeared
  int clip_frame = 0;       // 1 + the clip frame queued last; 0 while frame 0 leads
  int held = 0;             // times the current clip frame was queued
  long lines_at_hold = -1;  // PROGRESS's lines when the current frame had been held HOLD times
  for (int k = 0;; ++k) {
    int done_holding = held >= hold;
    if (done_holding && progress != NULL) {
      const long lines = countLines(progress);
      if (lines_at_hold < 0) lines_at_hold = lines;
      done_holding = lines >= lines_at_hold + 3 || held >= hold + 60 * 25;
    }
    if (clip_frame == frames && done_holding) break;
    if (clip_frame == 0 && access(go_file, F_OK) != 0 && lead < 60 * 25) {
      ++lead;
    } else if (clip_frame == 0 || done_holding) {
      ++clip_frame;
      held = 1;
      lines_at_hold = -1;
    } else {
      ++held;
    }
    const unsigned char* src = clip + frame_bytes * (size_t)(clip_frame == 0 ? 0 : clip_frame - 1);
    struct v4l2_buffer b = {.type = V4L2_BUF_TYPE_VIDEO_OUTPUT, .memory = V4L2_MEMORY_MMAP};
    if ((unsigned)k < buffers) {
      b.index = (unsigned)k;
    } else if (xioctl(out, VIDIOC_DQBUF, &b) < 0) {
      return fail("output DQBUF");
    }
    for (int y = 0; y < height; ++y) {
      if ((size_t)(y + 1) * out_fmt.bytesperline > length[b.index]) break;
      memcpy(mem[b.index] + (size_t)y * out_fmt.bytesperline, src + (size_t)y * (size_t)width,
             (size_t)width);
    }
    b.bytesused = out_fmt.sizeimage;
    if (xioctl(out, VIDIOC_QBUF, &b) < 0) return fail("output QBUF");
    if (!streaming && (unsigned)k + 1 == buffers) {
      enum v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      if (xioctl(out, VIDIOC_STREAMON, &type) < 0) return fail("output STREAMON");
      streaming = 1;
    }
  }
  // Let the queued frames go out, then stop. Not by dequeuing them all: vivid keeps the frame on
  // show until the next one comes, so the last DQBUF would wait forever.
  const struct timespec drain = {.tv_sec = 1, .tv_nsec = 0};
  nanosleep(&drain, NULL);
  enum v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
  xioctl(out, VIDIOC_STREAMOFF, &type);
  fprintf(stderr, "vivid-loop: played %d frames (frame 0 shown %d periods before) of %dx%d\n",
          frames, lead, width, height);
  free(clip);
  return 0;
}
