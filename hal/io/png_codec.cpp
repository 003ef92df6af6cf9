// PNG decoding with libpng's progressive-free "read" API from memory. libpng reports errors by
// longjmp, so the functions holding setjmp keep only trivially destructible locals.
#include <png.h>

#include <csetjmp>
#include <cstring>
#include <string>
#include <type_traits>

#include "hal/io/image_codec.hpp"

namespace epitrack::hal {
namespace {

/// The ancillary chunks libpng knows, other than tRNS (5 bytes each: name and NUL), ignored.
constexpr png_byte kIgnoredChunks[] = {
    'b', 'K', 'G', 'D', 0,   'c', 'H', 'R', 'M', 0,   'e', 'X', 'I', 'f', 0,   'g', 'A',
    'M', 'A', 0,   'h', 'I', 'S', 'T', 0,   'i', 'C', 'C', 'P', 0,   'i', 'T', 'X', 't',
    0,   'o', 'F', 'F', 's', 0,   'p', 'C', 'A', 'L', 0,   'p', 'H', 'Y', 's', 0,   's',
    'B', 'I', 'T', 0,   's', 'C', 'A', 'L', 0,   's', 'P', 'L', 'T', 0,   's', 'R', 'G',
    'B', 0,   't', 'E', 'X', 't', 0,   't', 'I', 'M', 'E', 0,   'z', 'T', 'X', 't', 0};

struct PngReadContext {
  const uint8_t* data;
  std::size_t size;
  std::size_t pos;
  char message[256];
};

void pngError(png_structp png, png_const_charp msg) {
  auto* ctx = static_cast<PngReadContext*>(png_get_error_ptr(png));
  std::snprintf(ctx->message, sizeof(ctx->message), "%s", msg);
  png_longjmp(png, 1);
}

void pngWarning(png_structp /*png*/, png_const_charp /*msg*/) {}

void pngRead(png_structp png, png_bytep out, png_size_t count) {
  auto* ctx = static_cast<PngReadContext*>(png_get_io_ptr(png));
  if (ctx->size - ctx->pos < count) png_error(png, "truncated PNG data");
  std::memcpy(out, ctx->data + ctx->pos, count);
  ctx->pos += count;
}

// Decodes (or only reads the header when out == nullptr). Returns 0 on success.
int pngDecodeImpl(PngReadContext* ctx, ImageHeader* header, ImageView<uint8_t>* out,
                  PngScratch* scratch) {
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, ctx, pngError, pngWarning);
  if (png == nullptr) {
    std::snprintf(ctx->message, sizeof(ctx->message), "libpng: out of memory");
    return -1;
  }
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    std::snprintf(ctx->message, sizeof(ctx->message), "libpng: out of memory");
    return -1;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return -1;
  }
  png_set_user_limits(png, kMaxImageDimension, kMaxImageDimension);
  // Only IHDR, PLTE, tRNS, IDAT and IEND matter for luma. libpng allocates an ancillary chunk's
  // claimed length before reading it, so a 100-byte file claiming a 1 GB sPLT chunk made it
  // allocate and clear 1 GB (found by fuzzing); the others are now skipped unread.
  png_set_keep_unknown_chunks(png, PNG_HANDLE_CHUNK_NEVER, kIgnoredChunks,
                              static_cast<int>(sizeof(kIgnoredChunks) / 5));
  png_set_read_fn(png, ctx, pngRead);
  png_read_info(png, info);
  const png_uint_32 w = png_get_image_width(png, info);
  const png_uint_32 h = png_get_image_height(png, info);
  const int color = png_get_color_type(png, info);
  const int depth = png_get_bit_depth(png, info);
  // Normalise to 8-bit gray or 8-bit RGB, alpha dropped.
  if (color == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (color == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (depth == 16) png_set_strip_16(png);
  if (color & PNG_COLOR_MASK_ALPHA) png_set_strip_alpha(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  const int channels = png_get_channels(png, info);
  header->width = static_cast<int>(w);
  header->height = static_cast<int>(h);
  header->channels = channels >= 3 ? 3 : 1;
  header->format = ImageFormat::kPng;
  if (out == nullptr) {
    png_destroy_read_struct(&png, &info, nullptr);
    return 0;
  }
  if (out->width != static_cast<int>(w) || out->height != static_cast<int>(h)) {
    std::snprintf(ctx->message, sizeof(ctx->message), "PNG is %ux%u, expected %dx%d", w, h,
                  out->width, out->height);
    png_destroy_read_struct(&png, &info, nullptr);
    return -1;
  }
  const int passes = png_set_interlace_handling(png);
  const std::size_t row_bytes = png_get_rowbytes(png, info);
  if (channels == 1 && passes == 1) {
    for (png_uint_32 y = 0; y < h; ++y) png_read_row(png, out->row(static_cast<int>(y)), nullptr);
  } else if (passes == 1) {
    scratch->pixels.resize(row_bytes);
    for (png_uint_32 y = 0; y < h; ++y) {
      png_read_row(png, scratch->pixels.data(), nullptr);
      const uint8_t* s = scratch->pixels.data();
      uint8_t* d = out->row(static_cast<int>(y));
      for (png_uint_32 x = 0; x < w; ++x, s += channels)
        d[x] = channels >= 3 ? rgbToLuma(s[0], s[1], s[2]) : s[0];
    }
  } else {
    // Interlaced: libpng needs the whole image and an array of pointers to its rows.
    scratch->pixels.resize(row_bytes * h);
    scratch->rows.resize(h);
    static_assert(std::is_same_v<png_bytep, uint8_t*>, "PngScratch::rows is libpng's row array");
    png_bytep* rows = scratch->rows.data();
    for (png_uint_32 y = 0; y < h; ++y) rows[y] = scratch->pixels.data() + row_bytes * y;
    png_read_image(png, rows);
    for (png_uint_32 y = 0; y < h; ++y) {
      const uint8_t* s = rows[y];
      uint8_t* d = out->row(static_cast<int>(y));
      for (png_uint_32 x = 0; x < w; ++x, s += channels)
        d[x] = channels >= 3 ? rgbToLuma(s[0], s[1], s[2]) : s[0];
    }
  }
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return 0;
}

}  // namespace

bool readPngHeader(const uint8_t* data, std::size_t size, ImageHeader& header, std::string& error) {
  PngReadContext ctx{data, size, 0, {}};
  if (pngDecodeImpl(&ctx, &header, nullptr, nullptr) != 0) {
    error = std::string("bad PNG: ") + ctx.message;
    return false;
  }
  return true;
}

bool decodePng(const uint8_t* data, std::size_t size, ImageView<uint8_t> out, PngScratch& scratch,
               std::string& error) {
  PngReadContext ctx{data, size, 0, {}};
  ImageHeader header;
  if (pngDecodeImpl(&ctx, &header, &out, &scratch) != 0) {
    error = std::string("bad PNG: ") + ctx.message;
    return false;
  }
  return true;
}

}  // namespace epitrack::hal
