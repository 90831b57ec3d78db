// A float RGB(A) image in memory, and the "write" stage: 8/16-bit PNG and
// half/float EXR (our own encoders), 16-bit TIFF and 8-bit TGA (OpenImageIO), written to a
// temporary file in the target's folder and renamed, so a failed bake never
// leaves a half-written map. OpenImageIO is a module loaded on first use
// (src/image/oiio.hpp); its types never leave it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/words.hpp"

namespace nmbake {

struct Image {
  int width = 0;
  int height = 0;
  int channels = 3;
  std::vector<float> pixels;  // row-major, y = 0 the top row, interleaved channels

  float* at(int x, int y) { return pixels.data() + (static_cast<std::size_t>(y) * width + x) * channels; }
  const float* at(int x, int y) const {
    return pixels.data() + (static_cast<std::size_t>(y) * width + x) * channels;
  }
};

// exr_half and exr_float are ZIP-compressed by our own writer (fast; float
// data barely shrinks under ZIP); exr_float_piz is float with PIZ through
// OpenImageIO: about a third smaller, about ten times slower to write.
// tga8: uncompressed 8-bit Targa through OpenImageIO.
enum class PixelFormat : std::uint8_t { png8, png16, tiff16, exr_half, exr_float, exr_float_piz, tga8 };
inline constexpr Word<PixelFormat> kPixelFormatWords[] = {
    {"png8", PixelFormat::png8, "8-bit PNG (dithered)"},
    {"png16", PixelFormat::png16, "16-bit PNG"},
    {"tiff16", PixelFormat::tiff16, "16-bit TIFF"},
    {"exr-half", PixelFormat::exr_half, "half-float EXR (ZIP)"},
    {"exr-float", PixelFormat::exr_float, "float EXR (ZIP)"},
    {"exr-float-piz", PixelFormat::exr_float_piz,
     "float EXR (PIZ): a third smaller, ten times slower to write"},
    {"tga", PixelFormat::tga8, "8-bit Targa (dithered)"},
};
NMBAKE_WORDS(PixelFormat, kPixelFormatWords)
// Whether the format stores 8 bits a sample (png8, tga8): the ones dithered.
bool is_8bit(PixelFormat format);
bool is_float_format(PixelFormat format);  // EXR: values stored as they are
// From the file extension: .png -> png16, .tif/.tiff -> tiff16, .exr -> exr_float, .tga -> tga8.
bool pixel_format_from_path(const std::string& path, PixelFormat& out);
// Whether `format` can be written to a file with this extension.
bool format_matches_extension(PixelFormat format, const std::string& path);

// Values are written as they are (no colour transform, no sRGB): integer
// formats quantise round(clamp(v, 0, 1) * max).
//
// Details (image.cpp): PNG files carry no gAMA/sRGB/iCCP/cHRM chunk, so
// viewers show the stored values unconverted; a 4th channel is written as
// unassociated alpha, unchanged; TIFF and EXR use lossless zip compression
// (EXR: Huffman-coded deflate streams, which every zlib inflates);
// no file carries a timestamp, so the same image always gives the same bytes.
// The file is written to ".<stem>.nmbake-tmp-<pid>-<n><ext>" in the target's
// folder and renamed over the target; on failure the temp file is removed
// and an existing target is left untouched.
// Errors: internal for an empty or malformed image or a non-finite value
// (NaN or infinity: callers must never pass one); bad_input for a format
// that does not match the extension; io for a missing folder or a failed
// OpenImageIO call or rename. Messages name the path.
//
// WriteOptions::dither: 8-bit formats are quantised with ordered dithering
// (quantise.hpp: a quasirandom R2 threshold from the texel's index, fixed,
// never random) instead of rounding; other formats ignore it. Off by default here:
// bake() turns it on for maps (BakeOptions::dither), previews and debug
// images stay rounded.
// WriteOptions::scale, offset: integer formats (PNG, TIFF, TGA) store
// v * scale + offset (then clamped to [0, 1] and quantised); float formats
// store v. The map set's height, curvature and thickness are stored this way
// (MapSet::integer_mapping), with no mapped copy of the image.
struct WriteOptions {
  bool dither = false;
  float scale = 1.0f;
  float offset = 0.0f;
  // Integer formats: the first three channels (one of a grey image) are
  // linear colours, stored sRGB-encoded (after scale and offset); alpha and
  // float formats stay linear.
  bool srgb = false;
};
Status write_image(const Image& image, const std::string& path, PixelFormat format,
                   const WriteOptions& options = {});

// Whether `format` can be written here: always for PNG and ZIP EXR; for TIFF
// and PIZ EXR,
// whether the OpenImageIO module loads (internal error naming it and where
// it was looked for if not). A bake checks before it starts.
Status check_image_writer(PixelFormat format);

// The largest side of an image read_image() reads: twice the largest map a
// bake writes (RELIABILITY.md, "Limits").
constexpr int kMaxReadSide = 65536;

// Reads any format OpenImageIO reads into float, 0..1 for integer formats,
// with the file's channels (alpha is returned as stored, not premultiplied).
// A NaN in the file is rejected (bad_input) so no NaN enters the program.
// The header is checked before the pixels are read: sides up to
// kMaxReadSide, no more samples than the file's compression can hold, and
// memory (RELIABILITY.md).
Status read_image(const std::string& path, Image& out);

// read_image() of an image file held in memory (`size` bytes: an image
// embedded in a mesh file, material.hpp), with the same checks; `name`
// stands for the path in messages, `format_hint` (the file's mime type or
// Assimp's hint, may be empty) only tells a Targa, which has no signature.
Status read_image_memory(const std::string& name, const unsigned char* bytes, std::size_t size,
                         const std::string& format_hint, Image& out);

// What a file holds, without reading its pixels: lets `nmbake diff` pick a
// tolerance from the quantisation step, and tests check what was written.
// (Added to the lead's contract by the image stage.)
struct ImageFileInfo {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::string file_format;  // OpenImageIO's name: "png", "tiff", "openexr", ...
  std::string data_type;    // "uint8", "uint16", "half", "float", ...
  std::string compression;  // as OpenImageIO reports it ("zip", ...), may be empty
};
Status read_image_info(const std::string& path, ImageFileInfo& out);

// The OpenImageIO library the image module runs with ("2.4.7") and the
// module's file, loading the module; on failure "" and `error` says why.
std::string openimageio_version(std::string& module_file, std::string& error);

}  // namespace nmbake
