// The OpenImageIO image module (libnmbake_oiio.so; see image_oiio.hpp for
// why it is a module): the TIFF, PIZ EXR and TGA writers and every reader.
//
// OpenImageIO 2.4 behaviour this file relies on (checked by image_test.cpp):
//  * TIFF writers un-premultiply an alpha channel unless
//    "oiio:UnassociatedAlpha" is 1, and the PNG reader premultiplies unless the
//    same hint is given to open(): we set it both ways so values round-trip;
//  * the TIFF and OpenEXR writers store the current time (TIFF DateTime, EXR
//    capDate) unless "DateTime" is set; set to "" the TIFF tag is left out and
//    the EXR attribute is empty, so files are byte-identical run to run;
//  * integer quantisation is ours (quantise.hpp, shared with PNG); OIIO gets
//    data already in the file's type and converts nothing.
#include "image/oiio.hpp"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include "image/quantise.hpp"

namespace nmbake::oiio_module {
namespace {

// OpenImageIO's per-thread or per-object error text, never empty.
std::string error_text(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  return text.empty() ? std::string("OpenImageIO gave no reason") : text;
}

struct FormatTraits {
  const char* plugin;  // given to ImageOutput::create
  OIIO::TypeDesc type;
  const char* compression;
};

bool traits_of(PixelFormat format, FormatTraits& out) {
  switch (format) {
    case PixelFormat::tiff16:
      out = {"tiff", OIIO::TypeDesc::UINT16, "zip"};
      return true;
    case PixelFormat::exr_float_piz:
      // Smaller than ZIP for float normals, whose low bits are noise: on the
      // demo map 31.6 MB in 0.54 s, where our ZIP writes 48.2 MB in 0.05 s.
      out = {"openexr", OIIO::TypeDesc::FLOAT, "piz"};
      return true;
    case PixelFormat::tga8:
      // Uncompressed: every Targa reader takes it (some engines' loaders
      // skip RLE), and a dithered normal map has few runs to encode.
      out = {"targa", OIIO::TypeDesc::UINT8, "none"};
      return true;
    case PixelFormat::exr_half:
    case PixelFormat::exr_float:
    case PixelFormat::png8:
    case PixelFormat::png16:
      return false;  // PNG and ZIP EXR are ours (image_png.cpp, image_exr.cpp)
  }
  return false;
}

Outcome write(const Image& image, const std::string& file, PixelFormat format, bool dither,
              std::string& reason) {
  FormatTraits traits;
  if (!traits_of(format, traits)) {
    reason = "the image module writes only TIFF, PIZ EXR and TGA";
    return Outcome::io_error;
  }
  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(traits.plugin);
  if (!out) {
    reason = std::string("no OpenImageIO writer for ") + traits.plugin + ": " + error_text(OIIO::geterror());
    return Outcome::io_error;
  }
  OIIO::ImageSpec spec(image.width, image.height, image.channels, traits.type);
  spec.attribute("compression", traits.compression);
  // Alpha (if any) is data like the rest: never (un)premultiplied.
  spec.attribute("oiio:UnassociatedAlpha", 1);
  // The TIFF and EXR writers stamp the current time unless told a date; an
  // empty one writes none, so the same bake gives the same bytes.
  spec.attribute("DateTime", "");
  if (!out->open(file, spec)) {
    reason = error_text(out->geterror());
    return Outcome::io_error;
  }
  bool written = false;
  if (traits.type == OIIO::TypeDesc::UINT16) {
    std::vector<std::uint16_t> data(image.pixels.size());
    for (std::size_t i = 0; i < data.size(); ++i) {
      data[i] = static_cast<std::uint16_t>(detail::quantise(image.pixels[i], 65535.0f));
    }
    written = out->write_image(OIIO::TypeDesc::UINT16, data.data());
  } else if (traits.type == OIIO::TypeDesc::UINT8) {
    std::vector<std::uint8_t> data(image.pixels.size());
    const auto channels = static_cast<std::size_t>(image.channels);
    const auto width = static_cast<std::size_t>(image.width);
    for (std::size_t i = 0; i < data.size(); ++i) {
      const std::size_t texel = i / channels;
      data[i] = static_cast<std::uint8_t>(
          dither ? detail::quantise_dithered(
                       image.pixels[i], 255.0f, static_cast<std::uint32_t>(texel % width),
                       static_cast<std::uint32_t>(texel / width), static_cast<std::uint32_t>(i % channels))
                 : detail::quantise(image.pixels[i], 255.0f));
    }
    written = out->write_image(OIIO::TypeDesc::UINT8, data.data());
  } else {
    written = out->write_image(OIIO::TypeDesc::FLOAT, image.pixels.data());  // float in, float out
  }
  if (!written) {
    reason = error_text(out->geterror());
    out->close();
    return Outcome::io_error;
  }
  if (!out->close()) {
    reason = error_text(out->geterror());
    return Outcome::io_error;
  }
  return Outcome::ok;
}

// The reader named `reader`, opened on `path`; never another reader (open()
// alone tries every plugin in turn until one takes the file).
// `memory` non-null: the reader reads it instead of a file (it must outlive `in`).
std::unique_ptr<OIIO::ImageInput> open_with(const std::string& path, const std::string& reader,
                                            const OIIO::ImageSpec* config, OIIO::Filesystem::IOProxy* memory,
                                            std::string& reason) {
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::create(reader);
  if (!in) {
    reason = "no OpenImageIO reader for " + reader + ": " + error_text(OIIO::geterror());
    return nullptr;
  }
  if (memory != nullptr && (!in->supports("ioproxy") || !in->set_ioproxy(memory))) {
    reason = "OpenImageIO's " + reader + " reader cannot read an image held in memory";
    return nullptr;
  }
  OIIO::ImageSpec spec;
  const bool opened = config ? in->open(path, spec, *config) : in->open(path, spec);
  if (!opened) {
    reason = error_text(in->geterror());
    return nullptr;
  }
  return in;
}

Outcome read_info(const std::string& path, const std::string& reader, const unsigned char* bytes,
                  std::size_t size, ImageFileInfo& out, std::string& reason) {
  std::unique_ptr<OIIO::Filesystem::IOMemReader> memory;
  if (bytes != nullptr) memory = std::make_unique<OIIO::Filesystem::IOMemReader>(bytes, size);
  std::unique_ptr<OIIO::ImageInput> in = open_with(path, reader, nullptr, memory.get(), reason);
  if (!in) return Outcome::bad_input;  // image.cpp has read its first bytes: the file is there
  const OIIO::ImageSpec& spec = in->spec();
  out.width = spec.width;
  out.height = spec.height;
  out.channels = spec.nchannels;
  out.file_format = in->format_name();
  out.data_type = spec.format.c_str();
  out.compression = spec.get_string_attribute("compression");
  if (!in->close()) {
    reason = error_text(in->geterror());
    return Outcome::io_error;
  }
  return Outcome::ok;
}

Outcome read(const std::string& path, const std::string& reader, const unsigned char* bytes, std::size_t size,
             Image& out, std::string& reason) {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  std::unique_ptr<OIIO::Filesystem::IOMemReader> memory;
  if (bytes != nullptr) {
    memory = std::make_unique<OIIO::Filesystem::IOMemReader>(bytes, size);
    void* proxy = memory.get();
    config.attribute("oiio:ioproxy", OIIO::TypeDesc::PTR, &proxy);
  }
  std::unique_ptr<OIIO::ImageInput> in = open_with(path, reader, &config, memory.get(), reason);
  if (!in) return Outcome::bad_input;
  const OIIO::ImageSpec spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth > 1) {
    reason = "not a 2D image (" + std::to_string(spec.width) + "x" + std::to_string(spec.height) + "x" +
             std::to_string(spec.depth) + ", " + std::to_string(spec.nchannels) + " channels)";
    return Outcome::bad_input;
  }
  Image image;
  image.width = spec.width;
  image.height = spec.height;
  image.channels = spec.nchannels;
  // image.cpp has bounded the header by the file's size and memory, but
  // OpenImageIO's own buffers may still ask for more than there is (before
  // the side limit, an 18.7M x 9 EXR made OpenEXR allocate 28.7 GB):
  // std::bad_alloc from it is the file's fault, not ours.
  try {
    image.pixels.resize(static_cast<std::size_t>(spec.width) * spec.height * spec.nchannels);
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.pixels.data())) {
      reason = error_text(in->geterror());
      return Outcome::io_error;
    }
  } catch (const std::bad_alloc&) {
    reason = "OpenImageIO cannot allocate what its header asks for (" + std::to_string(spec.width) + "x" +
             std::to_string(spec.height) + ", " + std::to_string(spec.nchannels) +
             " channels): a broken file";
    return Outcome::bad_input;
  }
  if (!in->close()) {
    reason = error_text(in->geterror());
    return Outcome::io_error;
  }
  out = std::move(image);
  return Outcome::ok;
}

// The OpenImageIO library this module runs with (its shared library, which
// may be newer than the headers it was built against).
std::string runtime_version() {
  const int version = OIIO::openimageio_version();
  return std::to_string(version / 10000) + "." + std::to_string(version / 100 % 100) + "." +
         std::to_string(version % 100);
}
const std::string kRuntimeVersion = runtime_version();

const Api api = {kAbiVersion, kRuntimeVersion.c_str(), write, read_info, read};

}  // namespace
}  // namespace nmbake::oiio_module

extern "C" __attribute__((visibility("default"))) const nmbake::oiio_module::Api* nmbake_oiio_module_api() {
  return &nmbake::oiio_module::api;
}
