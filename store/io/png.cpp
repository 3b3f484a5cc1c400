#include "specula/store/io/png_stack.h"

#include <png.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"

namespace specula::store {
namespace fs = std::filesystem;

namespace {

// libpng reports errors by longjmp-ing back to the setjmp in the step functions below. Those functions and
// the callbacks hold only trivially destructible state, so no C++ destructor is ever skipped; everything that
// owns memory lives in the callers, outside the jump.

struct PngReadState {
  png_structp png = nullptr;
  png_infop info = nullptr;
  const unsigned char* data = nullptr;
  std::size_t size = 0;
  std::size_t pos = 0;
  char message[256] = {};
};

struct PngWriteState {
  png_structp png = nullptr;
  png_infop info = nullptr;
  std::FILE* file = nullptr;
  char message[256] = {};
};

struct PngHeader {
  png_uint_32 width = 0, height = 0;
  std::size_t file_rowbytes = 0;  // before transformations
  std::size_t rowbytes = 0;       // after transformations
  int channels = 0;
  int bit_depth = 0;
};

void record_error(char (&message)[256], png_const_charp text) {
  std::snprintf(message, sizeof message, "%s", text ? text : "unknown libpng error");
}

void on_read_error(png_structp png, png_const_charp text) {
  record_error(static_cast<PngReadState*>(png_get_error_ptr(png))->message, text);
  png_longjmp(png, 1);
}

void on_write_error(png_structp png, png_const_charp text) {
  record_error(static_cast<PngWriteState*>(png_get_error_ptr(png))->message, text);
  png_longjmp(png, 1);
}

void on_warning(png_structp, png_const_charp) {}

void read_from_memory(png_structp png, png_bytep out, png_size_t length) {
  auto* state = static_cast<PngReadState*>(png_get_io_ptr(png));
  if (length > state->size - state->pos) png_error(png, "unexpected end of file (truncated PNG)");
  std::memcpy(out, state->data + state->pos, length);
  state->pos += length;
}

bool png_step_read_header(PngReadState* s, PngHeader* h) {
  if (setjmp(png_jmpbuf(s->png))) return false;
  png_set_read_fn(s->png, s, read_from_memory);
  png_read_info(s->png, s->info);
  int bit_depth = 0, color_type = 0;
  png_get_IHDR(s->png, s->info, &h->width, &h->height, &bit_depth, &color_type, nullptr, nullptr, nullptr);
  h->file_rowbytes = png_get_rowbytes(s->png, s->info);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(s->png);
  if (color_type == PNG_COLOR_TYPE_GRAY && bit_depth < 8) png_set_expand_gray_1_2_4_to_8(s->png);
  if (png_get_valid(s->png, s->info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(s->png);
  png_set_interlace_handling(s->png);
  png_read_update_info(s->png, s->info);
  h->rowbytes = png_get_rowbytes(s->png, s->info);
  h->channels = png_get_channels(s->png, s->info);
  h->bit_depth = png_get_bit_depth(s->png, s->info);
  return true;
}

bool png_step_read_rows(PngReadState* s, png_bytepp rows) {
  if (setjmp(png_jmpbuf(s->png))) return false;
  png_read_image(s->png, rows);
  png_read_end(s->png, nullptr);
  return true;
}

bool png_step_write(PngWriteState* s, png_uint_32 width, png_uint_32 height, int bit_depth, int color_type,
                    png_bytepp rows, bool fast = false) {
  if (setjmp(png_jmpbuf(s->png))) return false;
  png_init_io(s->png, s->file);
  if (fast) {  // for pictures sent over loopback: a few times larger, many times quicker
    png_set_compression_level(s->png, 1);
    png_set_filter(s->png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
  }
  png_set_IHDR(s->png, s->info, width, height, bit_depth, color_type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_write_info(s->png, s->info);
  png_write_image(s->png, rows);
  png_write_end(s->png, nullptr);
  return true;
}

class ReadHandle {
 public:
  explicit ReadHandle(const fs::path& path) {
    s_.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &s_, on_read_error, on_warning);
    if (s_.png) s_.info = png_create_info_struct(s_.png);
    if (!s_.png || !s_.info) throw LibraryError(path.string() + ": libpng could not allocate a PNG reader");
  }
  ~ReadHandle() { png_destroy_read_struct(&s_.png, &s_.info, nullptr); }
  ReadHandle(const ReadHandle&) = delete;
  ReadHandle& operator=(const ReadHandle&) = delete;
  PngReadState* get() { return &s_; }

 private:
  PngReadState s_;
};

class WriteHandle {
 public:
  WriteHandle(const fs::path& path, std::FILE* file) {
    s_.file = file;
    s_.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &s_, on_write_error, on_warning);
    if (s_.png) s_.info = png_create_info_struct(s_.png);
    if (!s_.png || !s_.info) throw LibraryError(path.string() + ": libpng could not allocate a PNG writer");
  }
  ~WriteHandle() { png_destroy_write_struct(&s_.png, &s_.info); }
  WriteHandle(const WriteHandle&) = delete;
  WriteHandle& operator=(const WriteHandle&) = delete;
  PngWriteState* get() { return &s_; }

 private:
  PngWriteState s_;
};

std::string read_file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open PNG file: " + std::strerror(errno));
  std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) throw InputError(path.string() + ": cannot read PNG file: " + std::strerror(errno));
  return bytes;
}

void check_size(const fs::path& path, std::size_t width, std::size_t height, std::size_t given, std::size_t per_pixel) {
  if (width == 0 || height == 0 || width > PNG_UINT_31_MAX || height > PNG_UINT_31_MAX)
    throw UsageError(path.string() + ": PNG size must be between 1 and 2^31-1 pixels per side, got " +
                     std::to_string(width) + " x " + std::to_string(height));
  if (given != width * height * per_pixel)
    throw UsageError(path.string() + ": expected " + std::to_string(width * height * per_pixel) + " samples for a " +
                     std::to_string(width) + " x " + std::to_string(height) + " PNG, got " + std::to_string(given));
}

void write_png(const fs::path& path, std::size_t width, std::size_t height, int bit_depth, int color_type,
               std::vector<png_bytep>& rows, bool fast = false) {
  AtomicOutput out(path);
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(out.temp_path().c_str(), "wb"), std::fclose);
  if (!file) throw LibraryError(out.temp_path().string() + ": cannot create file: " + std::strerror(errno));
  {
    WriteHandle handle(path, file.get());
    if (!png_step_write(handle.get(), static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), bit_depth,
                        color_type, rows.data(), fast))
      throw LibraryError(path.string() + ": libpng failed to write: " + handle.get()->message);
  }
  if (std::fflush(file.get()) != 0 || std::ferror(file.get()))
    throw LibraryError(path.string() + ": cannot write PNG file: " + std::strerror(errno));
  if (std::fclose(file.release()) != 0)
    throw LibraryError(path.string() + ": cannot close PNG file: " + std::strerror(errno));
  out.commit();
}

// Orders names with digit runs compared by value, so "band_2.png" sorts before "band_10.png".
bool natural_less(const std::string& a, const std::string& b) {
  std::size_t i = 0, j = 0;
  auto digit = [](char c) { return c >= '0' && c <= '9'; };
  while (i < a.size() && j < b.size()) {
    if (digit(a[i]) && digit(b[j])) {
      std::size_t i0 = i, j0 = j;
      while (i0 < a.size() && a[i0] == '0') ++i0;
      while (j0 < b.size() && b[j0] == '0') ++j0;
      std::size_t i1 = i0, j1 = j0;
      while (i1 < a.size() && digit(a[i1])) ++i1;
      while (j1 < b.size() && digit(b[j1])) ++j1;
      if (i1 - i0 != j1 - j0) return i1 - i0 < j1 - j0;
      int c = a.compare(i0, i1 - i0, b, j0, j1 - j0);
      if (c != 0) return c < 0;
      if (i1 - i != j1 - j) return i1 - i < j1 - j;
      i = i1;
      j = j1;
    } else {
      if (a[i] != b[j]) return static_cast<unsigned char>(a[i]) < static_cast<unsigned char>(b[j]);
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

std::vector<fs::path> pngs_in_directory(const fs::path& dir) {
  std::vector<fs::path> found;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::string ext = it->path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext == ".png" && it->is_regular_file()) found.push_back(it->path());
  }
  if (ec) throw InputError(dir.string() + ": cannot list directory: " + ec.message());
  std::sort(found.begin(), found.end(), [](const fs::path& a, const fs::path& b) {
    return natural_less(a.filename().string(), b.filename().string());
  });
  if (found.empty()) throw InputError(dir.string() + ": no *.png files in this directory");
  return found;
}

}  // namespace

PngImage read_png(const fs::path& path) {
  const std::string bytes = read_file_bytes(path);
  ReadHandle handle(path);
  PngReadState* s = handle.get();
  s->data = reinterpret_cast<const unsigned char*>(bytes.data());
  s->size = bytes.size();

  PngHeader h;
  if (!png_step_read_header(s, &h)) throw InputError(path.string() + ": corrupt or truncated PNG: " + s->message);
  // Deflate cannot compress by more than ~1032:1, so a header promising more pixels than the file could
  // hold is corrupt; rejecting it here avoids a huge allocation before libpng notices.
  const double claimed = (static_cast<double>(h.file_rowbytes) + 1.0) * h.height;
  if (claimed > 1040.0 * static_cast<double>(bytes.size()) + 65536.0)
    throw InputError(path.string() + ": corrupt or truncated PNG: header claims " + std::to_string(h.width) + " x " +
                     std::to_string(h.height) + " pixels, more than " + std::to_string(bytes.size()) +
                     " bytes can encode");
  if (h.bit_depth != 8 && h.bit_depth != 16)
    throw InputError(path.string() + ": unsupported PNG bit depth " + std::to_string(h.bit_depth));

  std::vector<unsigned char> pixels(h.rowbytes * h.height);
  std::vector<png_bytep> rows(h.height);
  for (std::size_t y = 0; y < h.height; ++y) rows[y] = pixels.data() + y * h.rowbytes;
  if (!png_step_read_rows(s, rows.data()))
    throw InputError(path.string() + ": corrupt or truncated PNG: " + s->message);

  PngImage image;
  image.width = h.width;
  image.height = h.height;
  image.channels = static_cast<std::size_t>(h.channels);
  image.bit_depth = h.bit_depth;
  const std::size_t per_row = image.width * image.channels;
  image.samples.resize(per_row * image.height);
  for (std::size_t y = 0; y < image.height; ++y) {
    const unsigned char* src = rows[y];
    std::uint16_t* dst = image.samples.data() + y * per_row;
    if (h.bit_depth == 16) {
      for (std::size_t i = 0; i < per_row; ++i) dst[i] = static_cast<std::uint16_t>((src[2 * i] << 8) | src[2 * i + 1]);
    } else {
      for (std::size_t i = 0; i < per_row; ++i) dst[i] = src[i];
    }
  }
  return image;
}

void write_png_rgb8(const fs::path& path, std::size_t width, std::size_t height, std::span<const std::uint8_t> rgb) {
  check_size(path, width, height, rgb.size(), 3);
  std::vector<png_bytep> rows(height);
  for (std::size_t y = 0; y < height; ++y) rows[y] = const_cast<png_bytep>(rgb.data() + y * width * 3);
  write_png(path, width, height, 8, PNG_COLOR_TYPE_RGB, rows);
}

std::vector<std::uint8_t> encode_png_rgb8(std::size_t width, std::size_t height, std::span<const std::uint8_t> rgb) {
  const fs::path label("<PNG in memory>");
  check_size(label, width, height, rgb.size(), 3);
  std::vector<png_bytep> rows(height);
  for (std::size_t y = 0; y < height; ++y) rows[y] = const_cast<png_bytep>(rgb.data() + y * width * 3);
  char* buffer = nullptr;
  std::size_t size = 0;
  std::FILE* memory = open_memstream(&buffer, &size);
  if (!memory) throw LibraryError("cannot open a memory stream for a PNG: " + std::string(std::strerror(errno)));
  std::unique_ptr<char, void (*)(void*)> owned(nullptr, std::free);
  {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(memory, std::fclose);
    WriteHandle handle(label, file.get());
    if (!png_step_write(handle.get(), static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8,
                        PNG_COLOR_TYPE_RGB, rows.data(), true))
      throw LibraryError("libpng failed to encode a PNG in memory: " + std::string(handle.get()->message));
    if (std::fclose(file.release()) != 0) throw LibraryError("cannot close a PNG memory stream");
  }
  owned.reset(buffer);
  return std::vector<std::uint8_t>(reinterpret_cast<const std::uint8_t*>(buffer),
                                   reinterpret_cast<const std::uint8_t*>(buffer) + size);
}

void write_png_gray16(const fs::path& path, std::size_t width, std::size_t height, std::span<const std::uint16_t> value,
                      bool fast) {
  check_size(path, width, height, value.size(), 1);
  std::vector<unsigned char> big_endian(value.size() * 2);
  for (std::size_t i = 0; i < value.size(); ++i) {
    big_endian[2 * i] = static_cast<unsigned char>(value[i] >> 8);
    big_endian[2 * i + 1] = static_cast<unsigned char>(value[i] & 0xff);
  }
  std::vector<png_bytep> rows(height);
  for (std::size_t y = 0; y < height; ++y) rows[y] = big_endian.data() + y * width * 2;
  write_png(path, width, height, 16, PNG_COLOR_TYPE_GRAY, rows, fast);
}

Cube read_png_stack(const std::vector<fs::path>& files, const WavelengthGrid& wavelengths) {
  if (files.empty()) throw UsageError("PNG stack: give one PNG file per band, or a directory of them");
  const bool from_directory = files.size() == 1 && fs::is_directory(files.front());
  const std::vector<fs::path> bands = from_directory ? pngs_in_directory(files.front()) : files;
  const std::string origin = from_directory ? files.front().string() : bands.front().string();
  if (bands.size() != wavelengths.size())
    throw InputError(origin + ": " + std::to_string(bands.size()) + " PNG files (one per band) but " +
                     std::to_string(wavelengths.size()) +
                     " wavelengths; give the `wavelengths` option with one wavelength per file, e.g. 400:700:10");

  Cube cube;
  const std::size_t count = bands.size();
  for (std::size_t b = 0; b < count; ++b) {
    const PngImage image = read_png(bands[b]);
    if (b == 0) {
      cube.resize(image.height, image.width, count);
    } else if (image.width != cube.width || image.height != cube.height) {
      throw InputError(bands[b].string() + ": PNG is " + std::to_string(image.width) + " x " +
                       std::to_string(image.height) + " but " + bands.front().string() + " is " +
                       std::to_string(cube.width) + " x " + std::to_string(cube.height) +
                       "; every band must have the same size");
    }
    const std::size_t ch = image.channels;
    const std::size_t pixels = image.width * image.height;
    if (ch >= 3) {
      for (std::size_t p = 0; p < pixels; ++p) {
        const std::uint16_t* s = image.samples.data() + p * ch;
        if (s[0] != s[1] || s[0] != s[2])
          throw InputError(bands[b].string() + ": colour PNG with R, G, B differing at pixel (" +
                           std::to_string(p % image.width) + ", " + std::to_string(p / image.width) +
                           "); a band stack needs grayscale PNGs");
      }
    }
    const double scale = image.bit_depth == 16 ? 1.0 / 65535.0 : 1.0 / 255.0;
    for (std::size_t p = 0; p < pixels; ++p)
      cube.data[p * count + b] = static_cast<float>(image.samples[p * ch] * scale);
  }
  cube.wavelengths = wavelengths;
  cube.provenance.source_file = origin;
  cube.provenance.importer = "png-stack";
  return cube;
}

}  // namespace specula::store
