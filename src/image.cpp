// Stage "write": PNG through our own parallel encoder (image_png.cpp), TIFF
// and OpenEXR through OpenImageIO 2.4; every image is read through OpenImageIO.
//
// Standards: PNG (ISO/IEC 15948) — no gAMA/sRGB/iCCP/cHRM chunk is written, so
// a normal map's bytes are shown and sampled as data; OpenEXR — lossless ZIP
// (half) or PIZ (float) compression.
//
// OpenImageIO 2.4 behaviour this file relies on (checked by image_test.cpp;
// the PNG points matter for reading, and for writing before image_png.cpp):
//  * the PNG writer adds a gAMA chunk for "oiio:ColorSpace" = "Linear" (gamma
//    1.0, which makes gamma-aware viewers brighten the image) and sRGB chunks
//    for "sRGB"; with no "oiio:ColorSpace" attribute it writes neither, which
//    is what we want, so we set none;
//  * PNG and TIFF writers un-premultiply an alpha channel unless
//    "oiio:UnassociatedAlpha" is 1, and the PNG reader premultiplies unless the
//    same hint is given to open(): we set it both ways so values round-trip;
//  * the TIFF and OpenEXR writers store the current time (TIFF DateTime, EXR
//    capDate) unless "DateTime" is set; set to "" the TIFF tag is left out and
//    the EXR attribute is empty, so files are byte-identical run to run;
//  * integer quantisation is ours (round(clamp(v, 0, 1) * max)); OIIO gets
//    data already in the file's type and converts nothing.
#include "nmbake/image.hpp"

#include <OpenImageIO/imageio.h>
#include "image_png.hpp"
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

namespace nmbake {

namespace fs = std::filesystem;

namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// OpenImageIO's per-thread or per-object error text, never empty.
std::string oiio_error_text(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  return text.empty() ? std::string("OpenImageIO gave no reason") : text;
}

struct FormatTraits {
  const char* oiio_format;  // plugin name given to ImageOutput::create
  OIIO::TypeDesc type;
  const char* compression;  // nullptr: the plugin's own (PNG is always deflate)
};

FormatTraits traits_of(PixelFormat format) {
  switch (format) {
    case PixelFormat::png8:
      return {"png", OIIO::TypeDesc::UINT8, nullptr};
    case PixelFormat::png16:
      return {"png", OIIO::TypeDesc::UINT16, nullptr};
    case PixelFormat::tiff16:
      return {"tiff", OIIO::TypeDesc::UINT16, "zip"};
    case PixelFormat::exr_half:
      return {"openexr", OIIO::TypeDesc::HALF, "zip"};
    case PixelFormat::exr_float:
      // PIZ, not ZIP: the low bits of float normals are noise to deflate; on
      // the demo map PIZ wrote 31.6 MB in 0.54 s where ZIP wrote 39.6 MB in
      // 0.72 s (both lossless; every OpenEXR reader has both).
      return {"openexr", OIIO::TypeDesc::FLOAT, "piz"};
  }
  NMBAKE_CHECK(false, "unknown PixelFormat");
  return {};
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

template <typename T>
std::vector<T> quantise(const std::vector<float>& pixels, float max_value) {
  std::vector<T> out(pixels.size());
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const float v = std::clamp(pixels[i], 0.0f, 1.0f);
    out[i] = static_cast<T>(std::lround(v * max_value));
  }
  return out;
}

// Writes the finished pixels to `temp` with OpenImageIO; the caller renames.
Status write_with_oiio(const Image& image, const std::string& path, const fs::path& temp,
                       PixelFormat format) {
  const FormatTraits traits = traits_of(format);
  const std::string temp_name = temp.string();

  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(traits.oiio_format);
  if (!out) {
    return Status::io("cannot write '" + path + "': no OpenImageIO writer for " + traits.oiio_format + ": " +
                      oiio_error_text(OIIO::geterror()));
  }

  OIIO::ImageSpec spec(image.width, image.height, image.channels, traits.type);
  if (traits.compression) spec.attribute("compression", traits.compression);
  // Alpha (if any) is data like the rest: never (un)premultiplied.
  spec.attribute("oiio:UnassociatedAlpha", 1);
  // The TIFF and EXR writers stamp the current time unless told a date; an
  // empty one writes none, so the same bake gives the same bytes.
  spec.attribute("DateTime", "");
  // zlib level 1: a 2048^2 16-bit normal map writes about 4x faster than at
  // the default level 6, for files about 8% larger.
  if (std::string(traits.oiio_format) == "png") spec.attribute("png:compressionLevel", 1);

  if (!out->open(temp_name, spec)) {
    return Status::io("cannot write '" + path + "': " + oiio_error_text(out->geterror()));
  }

  bool written = false;
  if (traits.type == OIIO::TypeDesc::UINT8) {
    const std::vector<std::uint8_t> data = quantise<std::uint8_t>(image.pixels, 255.0f);
    written = out->write_image(OIIO::TypeDesc::UINT8, data.data());
  } else if (traits.type == OIIO::TypeDesc::UINT16) {
    const std::vector<std::uint16_t> data = quantise<std::uint16_t>(image.pixels, 65535.0f);
    written = out->write_image(OIIO::TypeDesc::UINT16, data.data());
  } else {
    // Float in, half or float out: OpenImageIO (Imath) rounds to nearest half.
    written = out->write_image(OIIO::TypeDesc::FLOAT, image.pixels.data());
  }
  if (!written) {
    std::string reason = oiio_error_text(out->geterror());
    out->close();
    return Status::io("cannot write '" + path + "': " + reason);
  }
  if (!out->close()) {
    return Status::io("cannot write '" + path + "': " + oiio_error_text(out->geterror()));
  }
  return Status::ok();
}

}  // namespace

const char* to_string(PixelFormat format) {
  switch (format) {
    case PixelFormat::png8:
      return "png8";
    case PixelFormat::png16:
      return "png16";
    case PixelFormat::tiff16:
      return "tiff16";
    case PixelFormat::exr_half:
      return "exr-half";
    case PixelFormat::exr_float:
      return "exr-float";
  }
  return "unknown";
}

bool parse_pixel_format(const std::string& text, PixelFormat& out) {
  for (PixelFormat format : {PixelFormat::png8, PixelFormat::png16, PixelFormat::tiff16,
                             PixelFormat::exr_half, PixelFormat::exr_float}) {
    if (text == to_string(format)) {
      out = format;
      return true;
    }
  }
  return false;
}

bool pixel_format_from_path(const std::string& path, PixelFormat& out) {
  const std::string ext = lower_extension(path);
  if (ext == ".png") {
    out = PixelFormat::png16;
  } else if (ext == ".tif" || ext == ".tiff") {
    out = PixelFormat::tiff16;
  } else if (ext == ".exr") {
    out = PixelFormat::exr_float;
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
      return ext == ".exr";
  }
  return false;
}

Status write_image(const Image& image, const std::string& path, PixelFormat format) {
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
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    if (!std::isfinite(image.pixels[i])) {
      const std::size_t texel = i / image.channels;
      return Status::internal(
          "cannot write '" + path + "': " + (std::isnan(image.pixels[i]) ? "NaN" : "infinity") +
          " at pixel (" + std::to_string(texel % image.width) + ", " + std::to_string(texel / image.width) +
          ") channel " + std::to_string(i % image.channels));
    }
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

  const fs::path temp = temp_path_for(target.parent_path().empty() ? fs::path(".") / target : target);
  Status status = format == PixelFormat::png8 || format == PixelFormat::png16
                      ? image_detail::write_png(image, format == PixelFormat::png8 ? 8 : 16, temp.string(), path)
                      : write_with_oiio(image, path, temp, format);
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

Status read_image_info(const std::string& path, ImageFileInfo& out) {
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path);
  if (!in) return Status::io("cannot read '" + path + "': " + oiio_error_text(OIIO::geterror()));
  const OIIO::ImageSpec& spec = in->spec();
  out.width = spec.width;
  out.height = spec.height;
  out.channels = spec.nchannels;
  out.file_format = in->format_name();
  out.data_type = spec.format.c_str();
  out.compression = spec.get_string_attribute("compression");
  if (!in->close()) return Status::io("cannot read '" + path + "': " + oiio_error_text(in->geterror()));
  return Status::ok();
}

Status read_image(const std::string& path, Image& out) {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path, &config);
  if (!in) return Status::io("cannot read '" + path + "': " + oiio_error_text(OIIO::geterror()));
  const OIIO::ImageSpec spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth > 1) {
    return Status::bad_input("cannot read '" + path + "': not a 2D image (" + std::to_string(spec.width) +
                             "x" + std::to_string(spec.height) + "x" + std::to_string(spec.depth) + ", " +
                             std::to_string(spec.nchannels) + " channels)");
  }
  Image image;
  image.width = spec.width;
  image.height = spec.height;
  image.channels = spec.nchannels;
  image.pixels.resize(static_cast<std::size_t>(spec.width) * spec.height * spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.pixels.data())) {
    return Status::io("cannot read '" + path + "': " + oiio_error_text(in->geterror()));
  }
  if (!in->close()) return Status::io("cannot read '" + path + "': " + oiio_error_text(in->geterror()));
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    if (std::isnan(image.pixels[i])) {
      const std::size_t texel = i / image.channels;
      return Status::bad_input(
          "cannot read '" + path + "': NaN at pixel (" + std::to_string(texel % image.width) + ", " +
          std::to_string(texel / image.width) + ") channel " + std::to_string(i % image.channels));
    }
  }
  out = std::move(image);
  return Status::ok();
}

}  // namespace nmbake
