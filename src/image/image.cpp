// Stage "write": PNG and OpenEXR through our own parallel encoders
// (image_png.cpp, image_exr.cpp), TIFF through OpenImageIO 2.4; every image
// is read through OpenImageIO. OpenImageIO lives in a module loaded on first
// use (image_oiio.hpp): a PNG or EXR bake never pays its start-up cost.
//
// Standards: PNG (ISO/IEC 15948) — no gAMA/sRGB/iCCP/cHRM chunk is written, so
// a normal map's bytes are shown and sampled as data; OpenEXR — lossless ZIP
// compression, half or float samples.
#include "nmbake/image.hpp"

#include <dlfcn.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

#include "image/exr.hpp"
#include "image/oiio.hpp"
#include "image/png.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/color.hpp"
#include "nmbake/memory.hpp"

namespace nmbake {

namespace fs = std::filesystem;

namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// A name in the target's folder that keeps the extension (OpenImageIO picks
// behaviour by it) and starts with a dot (hidden, and never matches a glob of
// the real outputs). pid + counter keep concurrent writers apart.
fs::path temp_path_for(const fs::path& target) {
  static std::atomic<unsigned long> counter{0};
  const fs::path folder = target.parent_path();
  for (;;) {
    // Appended piece by piece: `"." + std::string` trips a GCC 12 -Wrestrict false positive.
    std::string name(1, '.');
    name += target.stem().string();
    name += ".nmbake-tmp-";
    name += std::to_string(::getpid());
    name += '-';
    name += std::to_string(counter.fetch_add(1));
    name += target.extension().string();
    fs::path candidate = folder / name;
    std::error_code ec;
    // A stale file left by a killed process with the same pid is skipped, not reused.
    if (!fs::exists(fs::symlink_status(candidate, ec))) return candidate;
  }
}

// The OpenImageIO module, loaded once: from $NMBAKE_MODULE_DIR when it is
// set, else from beside the executable, its parent folder (tests/ of a build
// tree) or ../lib/nmbake. Never unloaded.
// The module's file once image_module() found it (written once, under its once_flag).
std::string loaded_module_file;

const oiio_module::Api* image_module(std::string& error) {
  static std::once_flag once;
  static const oiio_module::Api* api = nullptr;
  static std::string failure;
  std::call_once(once, [] {
    std::vector<fs::path> folders;
    std::error_code ec;
    const char* dir = std::getenv("NMBAKE_MODULE_DIR");
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (dir && *dir) {
      folders.emplace_back(dir);
    } else if (!ec) {
      folders.push_back(exe.parent_path());
      folders.push_back(exe.parent_path().parent_path());
      folders.push_back(exe.parent_path().parent_path() / "lib" / "nmbake");
    }
    std::string looked;
    for (const fs::path& folder : folders) {
      const fs::path file = folder / oiio_module::kFileName;
      if (!fs::is_regular_file(file, ec)) {
        looked += (looked.empty() ? "" : ", ") + folder.string();
        continue;
      }
      void* handle = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (!handle) {
        const char* why = dlerror();
        failure = "cannot load the image module '" + file.string() + "': " + (why ? why : "unknown reason");
        return;
      }
      using Entry = const oiio_module::Api* (*)();
      const auto entry = reinterpret_cast<Entry>(dlsym(handle, oiio_module::kEntryPoint));
      const oiio_module::Api* found = entry ? entry() : nullptr;
      if (!found || found->abi_version != oiio_module::kAbiVersion) {
        failure = "the image module '" + file.string() + "' is from another build of nmbake";
        return;
      }
      api = found;
      loaded_module_file = file.string();
      return;
    }
    failure = std::string("the image module ") + oiio_module::kFileName +
              " (OpenImageIO: TIFF, PIZ EXR, TGA, and reading images) was not found in " + looked +
              "; set NMBAKE_MODULE_DIR to its folder";
  });
  if (!api) error = failure;
  return api;
}

Status module_status(oiio_module::Outcome outcome, const std::string& message) {
  switch (outcome) {
    case oiio_module::Outcome::ok:
      return Status::ok();
    case oiio_module::Outcome::bad_input:
      return Status::bad_input(message);
    case oiio_module::Outcome::io_error:
      break;
  }
  return Status::io(message);
}

// Writes the finished pixels to `temp` through the module; the caller renames.
Status write_with_oiio(const Image& image, const std::string& path, const fs::path& temp, PixelFormat format,
                       bool dither) {
  std::string reason;
  const oiio_module::Api* api = image_module(reason);
  if (!api) return Status::internal("cannot write '" + path + "': " + reason);
  const oiio_module::Outcome outcome = api->write(image, temp.string(), format, dither, reason);
  return module_status(outcome, "cannot write '" + path + "': " + reason);
}

// OpenImageIO tries reader after reader on a device or a FIFO and never
// finishes one that does not end (`preview --map /dev/full` hung): only a
// regular file goes in.
Status check_regular_file(const std::string& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status)) return Status::bad_input("cannot read '" + path + "': no such file");
  if (!fs::is_regular_file(status))
    return Status::bad_input("cannot read '" + path + "': not a regular file");
  return Status::ok();
}

// An OpenEXR header is a list of attributes (name, type, byte size, value)
// ended by an empty name; a multi-part file has one header a part, ended by
// an empty header. What OpenEXR sizes from a header before any check of ours
// could run is checked here first, from the bytes:
//  * every attribute's size against the bytes left in the file (OpenEXR
//    allocates an attribute of a type it does not know at the size the file
//    states, up to 2 GB for a file of a few bytes; ASan zeroes it, and
//    fuzz_image ran at 10 inputs a second);
//  * each part's data window against kMaxReadSide, and its chunk count (rows
//    over the compression's lines a chunk, or tiles) against the file, which
//    holds an 8-byte offset a chunk (OpenEXR allocates the offset table in
//    open()).
// `f` holds `file_bytes` bytes (a file, or an embedded image through
// fmemopen); `path` names it in messages.
Status check_exr_header(const std::string& path, std::FILE* f, std::uintmax_t file_bytes) {
  const auto broken = [&](const std::string& why) {
    return Status::bad_input("cannot read '" + path + "': a broken EXR header: " + why);
  };
  const auto u32 = [](const unsigned char* b) {
    return static_cast<std::uint32_t>(b[0]) | static_cast<std::uint32_t>(b[1]) << 8 |
           static_cast<std::uint32_t>(b[2]) << 16 | static_cast<std::uint32_t>(b[3]) << 24;
  };
  unsigned char head[8];
  if (std::fread(head, 1, sizeof head, f) != sizeof head) return broken("the file ends in its first 8 bytes");
  const bool multipart = (head[5] & 0x10) != 0;  // version flags: bit 12
  const bool tiled = (head[5] & 0x02) != 0;      // bit 9 (single-part files)
  // A name or type: up to 255 bytes and a NUL; an empty name ends a header.
  const auto read_name = [&](std::string& name) {
    name.clear();
    for (int c = std::fgetc(f); c != EOF; c = std::fgetc(f)) {
      if (c == 0) return true;
      if (name.size() == 255) return false;
      name.push_back(static_cast<char>(c));
    }
    return false;
  };
  std::string name, type;
  for (int part = 0;; ++part) {
    int attributes = 0;
    std::int64_t width = -1, height = -1, tile_x = 0, tile_y = 0;
    int compression = 0;
    for (;; ++attributes) {
      if (!read_name(name)) return broken("an attribute name is longer than 255 bytes or runs past the end");
      if (name.empty()) break;
      const std::string shown_name = printable_text(name);
      if (!read_name(type)) return broken("the type of '" + shown_name + "' runs past the end");
      unsigned char size_bytes[4];
      if (std::fread(size_bytes, 1, 4, f) != 4)
        return broken("the file ends in the size of '" + shown_name + "'");
      const std::uint32_t size = u32(size_bytes);
      const long at = std::ftell(f);
      if (at < 0) return Status::io("cannot read '" + path + "': " + std::strerror(errno));
      const std::uintmax_t left = file_bytes - static_cast<std::uintmax_t>(at);
      if (size > 0x7fffffffu || size > left) {
        return broken("attribute '" + shown_name + "' claims " + std::to_string(size) + " bytes, " +
                      std::to_string(left) + " are left in the file");
      }
      unsigned char value[16];
      const bool window = name == "dataWindow" && type == "box2i" && size == 16;
      const bool tiles = name == "tiles" && type == "tiledesc" && size == 9;
      const bool packing = name == "compression" && type == "compression" && size == 1;
      if (window || tiles || packing) {
        if (std::fread(value, 1, size, f) != size) return broken("the file ends in '" + shown_name + "'");
        if (window) {
          const auto corner = [&](int i) {
            return static_cast<std::int64_t>(static_cast<std::int32_t>(u32(value + 4 * i)));
          };
          width = corner(2) - corner(0) + 1;
          height = corner(3) - corner(1) + 1;
        } else if (tiles) {
          tile_x = u32(value);
          tile_y = u32(value + 4);
        } else {
          compression = value[0];
        }
      } else if (std::fseek(f, static_cast<long>(size), SEEK_CUR) != 0) {
        return Status::io("cannot read '" + path + "': " + std::strerror(errno));
      }
    }
    if (attributes == 0) break;  // the empty header that ends a multi-part file
    if (width > kMaxReadSide || height > kMaxReadSide) {
      return Status::bad_input("cannot read '" + path + "': its header says " + std::to_string(width) + "x" +
                               std::to_string(height) + "; nmbake reads images of at most " +
                               std::to_string(kMaxReadSide) + " pixels a side");
    }
    if (width > 0 && height > 0) {
      // Lines a chunk by compression (none, RLE, ZIPS, ZIP, PIZ, PXR24, B44,
      // B44A, DWAA, DWAB); a tiled part has at least one chunk a tile.
      static constexpr int kLines[] = {1, 1, 1, 16, 32, 16, 32, 32, 32, 256};
      const std::int64_t lines = compression < 10 ? kLines[compression] : 1;
      std::int64_t chunks = (height + lines - 1) / lines;
      if ((tiled || multipart) && tile_x > 0 && tile_y > 0) {
        chunks = ((width + tile_x - 1) / tile_x) * ((height + tile_y - 1) / tile_y);
      }
      if (static_cast<std::uintmax_t>(chunks) * 8u > file_bytes) {
        return Status::bad_input("cannot read '" + path + "': its header says " + std::to_string(width) +
                                 "x" + std::to_string(height) + " in " + std::to_string(chunks) +
                                 " chunks, whose offsets alone " + std::to_string(file_bytes) +
                                 " bytes of openexr cannot hold: a broken or truncated file");
      }
    }
    if (!multipart) break;
    if (part >= 4096) return broken("more than 4096 parts");
  }
  return Status::ok();
}

Status check_exr_header(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return Status::io("cannot read '" + path + "': " + std::strerror(errno));
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> closer(f, &std::fclose);
  std::error_code ec;
  const std::uintmax_t file_bytes = fs::file_size(path, ec);
  if (ec) return Status::io("cannot read '" + path + "': " + ec.message());
  return check_exr_header(path, f, file_bytes);
}

// The OpenImageIO reader for the formats nmbake reads, picked from the
// file's first bytes (a Targa, which has no signature, from its extension),
// so that no other reader sees the file: OpenImageIO's open() offers a file
// to every plugin in turn, and some allocate the whole image from the header
// inside open(), before check_image_header() can run (a 30-byte WebP
// claiming 12546 x 13317 took 670 MB there; found by tests/fuzz).
// `head`: the first `got` (up to 12) bytes; `extension` (".tga") names a
// Targa, which has no signature.
Status pick_reader(const std::string& path, const unsigned char* head, std::size_t got, std::string extension,
                   std::string& reader) {
  const auto starts = [&](const char* magic, std::size_t n) {
    return got >= n && std::memcmp(head, magic, n) == 0;
  };
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (starts("\x89PNG\r\n\x1a\n", 8)) {
    reader = "png";
  } else if (starts("\x76\x2f\x31\x01", 4)) {
    reader = "openexr";
  } else if (starts("II*\0", 4) || starts("MM\0*", 4) || starts("II+\0", 4) || starts("MM\0+", 4)) {
    reader = "tiff";
  } else if (starts("\xff\xd8\xff", 3)) {
    reader = "jpeg";
  } else if (starts("BM", 2)) {
    reader = "bmp";
  } else if (starts("#?RADIANCE", 10) || starts("#?RGBE", 6)) {
    reader = "hdr";
  } else if (got >= 2 && head[0] == 'P' && head[1] >= '1' && head[1] <= '6') {
    reader = "pnm";
  } else if (starts("\x01\xda", 2)) {
    reader = "sgi";
  } else if (extension == ".tga" || extension == ".tpic") {
    reader = "targa";
  } else {
    return Status::bad_input("cannot read '" + path +
                             "': not an image nmbake reads (PNG, EXR, TIFF, JPEG, Targa, BMP, HDR, PNM, SGI: "
                             "its first bytes are none of theirs)");
  }
  return Status::ok();
}

Status pick_reader(const std::string& path, std::string& reader) {
  unsigned char head[12] = {};
  std::size_t got = 0;
  if (std::FILE* f = std::fopen(path.c_str(), "rb")) {
    got = std::fread(head, 1, sizeof head, f);
    std::fclose(f);
  } else {
    return Status::io("cannot read '" + path + "': " + std::strerror(errno));
  }
  return pick_reader(path, head, got, fs::path(path).extension().string(), reader);
}

// Bytes of one sample as the file stores it (OpenImageIO's type names).
double stored_sample_bytes(const std::string& data_type) {
  if (data_type == "half" || data_type == "uint16" || data_type == "int16") return 2.0;
  if (data_type == "float" || data_type == "uint" || data_type == "int") return 4.0;
  if (data_type == "double") return 8.0;
  return 1.0;
}

// The largest expansion of an OpenEXR compression (OpenImageIO's name of it,
// e.g. "zip" or "dwaa:45"): deflate-based and the others stay under deflate's
// 1032:1 (measured on a constant 4096^2 half image: ZIP 764, PXR24 709, PIZ
// 253, RLE 60, B44A 10); DWAA/DWAB code an all-zero block's AC coefficients as
// one symbol before Huffman-coding them (measured 3388 and 11204), bounded
// here by 1032 x 64.
double exr_largest_ratio(const std::string& compression) {
  if (compression.rfind("dwa", 0) == 0) return 1032.0 * 64.0;
  return 1032.0;
}

// The header's size against what the file can hold and what memory allows.
// No side may pass kMaxReadSide. Formats whose compression has a known
// largest ratio bound the pixels by the file's size: a PNG's rows are
// deflated, and deflate expands at most 1032:1 (each row a filter byte and at
// least one bit a sample: OpenImageIO reports 1-, 2- and 4-bit PNGs as
// uint8); an EXR's samples by its compression's ratio (exr_largest_ratio); a
// TIFF's or JPEG's samples by 4096:1 (above LZW's ~2730, deflate's 1032 and
// a flat JPEG's ~190); a Targa, BMP, SGI or Radiance HDR run covers at most
// 128 pixels per byte of file (their RLE packets), a PNM holds at least a bit
// a pixel. Then the float image against memory. (A 25-byte Targa claiming
// 19789 x 15104 took 1.2 GB and seconds; a 422-byte ZIP EXR of 18743296 x 9
// made OpenEXR's chunk buffers ask for 1.8 GB each, 28.7 GB in all under the
// fuzzer; both found by tests/fuzz.)
Status check_image_header(const std::string& path, const ImageFileInfo& info, std::uintmax_t file_bytes,
                          bool size_known) {
  const std::uint64_t width = static_cast<std::uint64_t>(std::max(0, info.width));
  const std::uint64_t height = static_cast<std::uint64_t>(std::max(0, info.height));
  const std::uint64_t channels = static_cast<std::uint64_t>(std::max(0, info.channels));
  if (width > kMaxReadSide || height > kMaxReadSide) {
    return Status::bad_input("cannot read '" + path + "': its header says " + std::to_string(width) + "x" +
                             std::to_string(height) + "; nmbake reads images of at most " +
                             std::to_string(kMaxReadSide) + " pixels a side");
  }
  const double file = static_cast<double>(file_bytes);
  const double pixels = static_cast<double>(width) * static_cast<double>(height);
  const double samples = pixels * static_cast<double>(channels);
  double most = -1.0;  // the most the file can hold; < 0: not bounded
  double needed = pixels;
  if (info.file_format == "png") {
    const double bits = info.data_type == "uint16" ? 16.0 : 1.0;
    needed = static_cast<double>(height) *
             (1.0 + std::ceil(static_cast<double>(width) * static_cast<double>(channels) * bits / 8.0));
    most = 1032.0 * file;  // bytes of rows
  } else if (info.file_format == "openexr") {
    needed = samples * stored_sample_bytes(info.data_type);
    most = exr_largest_ratio(info.compression) * file;
  } else if (info.file_format == "tiff" || info.file_format == "jpeg") {
    needed = samples * stored_sample_bytes(info.data_type);
    most = 4096.0 * file;
  } else if (info.file_format == "targa" || info.file_format == "bmp" || info.file_format == "sgi" ||
             info.file_format == "hdr") {
    most = 128.0 * file;
  } else if (info.file_format == "pnm") {
    most = 8.0 * file;
  }
  if (size_known && most >= 0.0 && needed > most + 65536.0) {
    return Status::bad_input("cannot read '" + path + "': its header says " + std::to_string(width) + "x" +
                             std::to_string(height) + ", which " + std::to_string(file_bytes) + " bytes of " +
                             info.file_format + " cannot hold: a broken or truncated file");
  }
  return check_image_memory(path, width, height, channels);
}

Status check_image_header(const std::string& path, const ImageFileInfo& info) {
  std::error_code ec;
  const std::uintmax_t file_bytes = fs::file_size(path, ec);
  return check_image_header(path, info, file_bytes, !ec);
}

// No NaN enters the program.
Status check_no_nan(const std::string& path, const Image& image) {
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    if (std::isnan(image.pixels[i])) {
      const std::size_t texel = i / image.channels;
      return Status::bad_input(
          "cannot read '" + path + "': NaN at pixel (" + std::to_string(texel % image.width) + ", " +
          std::to_string(texel / image.width) + ") channel " + std::to_string(i % image.channels));
    }
  }
  return Status::ok();
}

}  // namespace

bool is_8bit(PixelFormat format) { return format == PixelFormat::png8 || format == PixelFormat::tga8; }

bool is_float_format(PixelFormat format) {
  return format == PixelFormat::exr_half || format == PixelFormat::exr_float ||
         format == PixelFormat::exr_float_piz;
}

bool pixel_format_from_path(const std::string& path, PixelFormat& out) {
  const std::string ext = lower_extension(path);
  if (ext == ".png") {
    out = PixelFormat::png16;
  } else if (ext == ".tif" || ext == ".tiff") {
    out = PixelFormat::tiff16;
  } else if (ext == ".exr") {
    out = PixelFormat::exr_float;
  } else if (ext == ".tga") {
    out = PixelFormat::tga8;
  } else {
    return false;
  }
  return true;
}

bool format_matches_extension(PixelFormat format, const std::string& path) {
  const std::string ext = lower_extension(path);
  switch (format) {
    case PixelFormat::png8:
    case PixelFormat::png16:
      return ext == ".png";
    case PixelFormat::tiff16:
      return ext == ".tif" || ext == ".tiff";
    case PixelFormat::exr_half:
    case PixelFormat::exr_float:
    case PixelFormat::exr_float_piz:
      return ext == ".exr";
    case PixelFormat::tga8:
      return ext == ".tga";
  }
  return false;
}

namespace {

// The index of the first NaN or infinity in `values`, or values.size(). A
// block's test has no early exit, so it vectorises; only a block with one
// is searched value by value.
std::size_t first_non_finite(const std::vector<float>& values) {
  constexpr std::size_t kBlock = 4096;
  for (std::size_t begin = 0; begin < values.size(); begin += kBlock) {
    const std::size_t end = std::min(values.size(), begin + kBlock);
    int bad = 0;
    for (std::size_t i = begin; i < end; ++i)
      bad |= !(std::fabs(values[i]) <= std::numeric_limits<float>::max());
    if (bad == 0) continue;
    for (std::size_t i = begin; i < end; ++i) {
      if (!std::isfinite(values[i])) return i;
    }
  }
  return values.size();
}

// v * scale + offset for every value, for the writers that quantise on
// their own (the OpenImageIO module's TIFF and TGA).
Image mapped_copy(const Image& image, float scale, float offset) {
  Image out;
  out.width = image.width;
  out.height = image.height;
  out.channels = image.channels;
  out.pixels.resize(image.pixels.size());
  for (std::size_t i = 0; i < out.pixels.size(); ++i) out.pixels[i] = image.pixels[i] * scale + offset;
  return out;
}

// The sRGB encoding of v * scale + offset for the colour channels (the
// first three, or the first of one or two), alpha as it is.
Image srgb_copy(const Image& image, float scale, float offset) {
  Image out = mapped_copy(image, scale, offset);
  const auto c = static_cast<std::size_t>(image.channels);
  const std::size_t colour = c >= 3 ? 3 : 1;
  for (std::size_t i = 0; i < out.pixels.size(); ++i) {
    if (i % c < colour) out.pixels[i] = linear_to_srgb(out.pixels[i]);
  }
  return out;
}

}  // namespace

Status write_image(const Image& image, const std::string& path, PixelFormat format,
                   const WriteOptions& options) {
  // Caller bugs first: they are internal errors, not the user's.
  if (image.width <= 0 || image.height <= 0 || image.channels <= 0) {
    return Status::internal("cannot write '" + path + "': empty image (" + std::to_string(image.width) + "x" +
                            std::to_string(image.height) + ", " + std::to_string(image.channels) +
                            " channels)");
  }
  const std::size_t expected =
      static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) * image.channels;
  if (image.pixels.size() != expected) {
    return Status::internal("cannot write '" + path + "': image holds " +
                            std::to_string(image.pixels.size()) + " values, " + std::to_string(expected) +
                            " expected");
  }
  if (!std::isfinite(options.scale) || !std::isfinite(options.offset)) {
    return Status::internal("cannot write '" + path + "': the integer mapping v * " +
                            std::to_string(options.scale) + " + " + std::to_string(options.offset) +
                            " is not finite");
  }
  if (const std::size_t i = first_non_finite(image.pixels); i < image.pixels.size()) {
    const std::size_t texel = i / image.channels;
    return Status::internal("cannot write '" + path +
                            "': " + (std::isnan(image.pixels[i]) ? "NaN" : "infinity") + " at pixel (" +
                            std::to_string(texel % image.width) + ", " + std::to_string(texel / image.width) +
                            ") channel " + std::to_string(i % image.channels));
  }

  if (!format_matches_extension(format, path)) {
    return Status::bad_input("cannot write '" + path + "': format " + to_string(format) +
                             " does not match the file extension '" + fs::path(path).extension().string() +
                             "'");
  }

  const fs::path target(path);
  if (target.filename().empty()) {
    return Status::bad_input("cannot write '" + path + "': not a file name");
  }
  const fs::path folder = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    return Status::io("cannot write '" + path + "': folder '" + folder.string() + "' does not exist");
  }

  if (options.srgb && !is_float_format(format)) {
    WriteOptions encoded = options;
    encoded.srgb = false;
    encoded.scale = 1.0f;
    encoded.offset = 0.0f;
    return write_image(srgb_copy(image, options.scale, options.offset), path, format, encoded);
  }
  NMBAKE_TRY(check_output_target(path));
  const fs::path temp = temp_path_for(target.parent_path().empty() ? fs::path(".") / target : target);
  const TempFileGuard guard(temp.string());  // removed if a signal ends the process meanwhile
  Status status;
  switch (format) {
    case PixelFormat::png8:
    case PixelFormat::png16:
      status = image_detail::write_png(image, format == PixelFormat::png8 ? 8 : 16, temp.string(), path,
                                       options.dither, options.scale, options.offset);
      break;
    case PixelFormat::exr_half:
    case PixelFormat::exr_float:
      status = image_detail::write_exr(image, format == PixelFormat::exr_half, temp.string(), path);
      break;
    case PixelFormat::exr_float_piz:
      status = write_with_oiio(image, path, temp, format, options.dither);
      break;
    case PixelFormat::tiff16:
    case PixelFormat::tga8:
      if (options.scale == 1.0f && options.offset == 0.0f) {
        status = write_with_oiio(image, path, temp, format, options.dither);
      } else {
        status = write_with_oiio(mapped_copy(image, options.scale, options.offset), path, temp, format,
                                 options.dither);
      }
      break;
  }
  if (status.is_ok()) {
    fs::rename(temp, target, ec);
    if (ec)
      status =
          Status::io("cannot write '" + path + "': renaming the finished temp file failed: " + ec.message());
  }
  if (!status.is_ok()) {
    std::error_code ignored;
    fs::remove(temp, ignored);
  }
  return status;
}

Status check_image_writer(PixelFormat format) {
  // PNG and ZIP EXR are ours; TIFF, PIZ EXR and TGA need the module.
  if (format != PixelFormat::tiff16 && format != PixelFormat::exr_float_piz && format != PixelFormat::tga8) {
    return Status::ok();
  }
  std::string reason;
  if (!image_module(reason))
    return Status::internal(std::string("cannot write ") + to_string(format) + ": " + reason);
  return Status::ok();
}

Status read_image_info(const std::string& path, ImageFileInfo& out) {
  NMBAKE_TRY(check_regular_file(path));
  std::string reason;
  const oiio_module::Api* api = image_module(reason);
  if (!api) return Status::internal("cannot read '" + path + "': " + reason);
  std::string reader;
  NMBAKE_TRY(pick_reader(path, reader));
  if (reader == "openexr") NMBAKE_TRY(check_exr_header(path));
  const oiio_module::Outcome outcome = api->read_info(path, reader, nullptr, 0, out, reason);
  return module_status(outcome, "cannot read '" + path + "': " + reason);
}

Status read_image(const std::string& path, Image& out) {
  NMBAKE_TRY(check_regular_file(path));
  std::string reason;
  const oiio_module::Api* api = image_module(reason);
  if (!api) return Status::internal("cannot read '" + path + "': " + reason);
  // The header first: a file that claims 1,000,000^2 pixels must be refused
  // before the pixels are allocated (it made std::bad_alloc, or took 4.7 GB
  // for 20000^2 before failing on the missing data).
  std::string reader;
  NMBAKE_TRY(pick_reader(path, reader));
  if (reader == "openexr") NMBAKE_TRY(check_exr_header(path));
  ImageFileInfo info;
  const oiio_module::Outcome header = api->read_info(path, reader, nullptr, 0, info, reason);
  if (header != oiio_module::Outcome::ok)
    return module_status(header, "cannot read '" + path + "': " + reason);
  NMBAKE_TRY(check_image_header(path, info));
  Image image;
  const oiio_module::Outcome outcome = api->read(path, reader, nullptr, 0, image, reason);
  if (outcome != oiio_module::Outcome::ok)
    return module_status(outcome, "cannot read '" + path + "': " + reason);
  NMBAKE_TRY(check_no_nan(path, image));
  out = std::move(image);
  return Status::ok();
}

Status read_image_memory(const std::string& name, const unsigned char* bytes, std::size_t size,
                         const std::string& format_hint, Image& out) {
  std::string reason;
  const oiio_module::Api* api = image_module(reason);
  if (!api) return Status::internal("cannot read '" + name + "': " + reason);
  if (size == 0) return Status::bad_input("cannot read '" + name + "': it holds no bytes");
  // The same checks as for a file, on the bytes: the reader from the first
  // bytes (a Targa from the hint: "tga", "image/x-tga"), the EXR header
  // walked through fmemopen, the header against the size and memory.
  std::string extension;
  if (format_hint.find("tga") != std::string::npos || format_hint.find("targa") != std::string::npos) {
    extension = ".tga";
  }
  std::string reader;
  NMBAKE_TRY(pick_reader(name, bytes, std::min<std::size_t>(size, 12), extension, reader));
  if (reader == "openexr") {
    std::FILE* f = ::fmemopen(const_cast<unsigned char*>(bytes), size, "rb");
    if (!f) return Status::io("cannot read '" + name + "': " + std::strerror(errno));
    const std::unique_ptr<std::FILE, int (*)(std::FILE*)> closer(f, &std::fclose);
    NMBAKE_TRY(check_exr_header(name, f, size));
  }
  ImageFileInfo info;
  const oiio_module::Outcome header = api->read_info(name, reader, bytes, size, info, reason);
  if (header != oiio_module::Outcome::ok)
    return module_status(header, "cannot read '" + name + "': " + reason);
  NMBAKE_TRY(check_image_header(name, info, size, true));
  Image image;
  const oiio_module::Outcome outcome = api->read(name, reader, bytes, size, image, reason);
  if (outcome != oiio_module::Outcome::ok)
    return module_status(outcome, "cannot read '" + name + "': " + reason);
  NMBAKE_TRY(check_no_nan(name, image));
  out = std::move(image);
  return Status::ok();
}

std::string openimageio_version(std::string& module_file, std::string& error) {
  const oiio_module::Api* api = image_module(error);
  if (!api) return "";
  module_file = loaded_module_file;
  return api->oiio_version;
}

}  // namespace nmbake
