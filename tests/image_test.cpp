// Tests of the "write" stage: format names, round trips through every
// format, what OpenImageIO actually put in the files, atomic replacement and
// the rejection of bad calls.
#include "nmbake/image.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "image/deflate_huffman.hpp"
#include "image/exr.hpp"
#include "image/png.hpp"
#include "image/quantise.hpp"
#include "test_util.hpp"
// Imath's half is the reference for ours; its computed conversions, so
// nothing to link.
#define IMATH_HALF_NO_LOOKUP_TABLE
#include <Imath/half.h>
#include <tbb/global_control.h>

namespace nmbake {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

// Values in and slightly out of [0, 1], including both ends and midpoints.
Image make_image(int width, int height, int channels) {
  Image image;
  image.width = width;
  image.height = height;
  image.channels = channels;
  image.pixels.resize(static_cast<std::size_t>(width) * height * channels);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    image.pixels[i] = -0.1f + 1.2f * static_cast<float>((i * 7919) % 1001) / 1000.0f;
  }
  image.pixels[0] = 0.0f;
  image.pixels[1] = 1.0f;
  image.pixels[2] = 0.5f;
  return image;
}

std::vector<std::string> list_dir(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct PngChunk {
  std::string type;
  std::string data;
};

// The chunk list of a PNG file, read by hand so the test does not trust the
// library that wrote it.
std::vector<PngChunk> png_chunks(const std::string& path) {
  const std::string bytes = read_bytes(path);
  std::vector<PngChunk> chunks;
  if (bytes.size() < 8 || bytes.compare(0, 8, "\x89PNG\r\n\x1a\n") != 0) return chunks;
  std::size_t at = 8;
  while (at + 12 <= bytes.size()) {
    const auto byte = [&](std::size_t i) {
      return static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i]));
    };
    const std::uint32_t length = byte(at) << 24 | byte(at + 1) << 16 | byte(at + 2) << 8 | byte(at + 3);
    if (at + 12 + length > bytes.size()) break;
    chunks.push_back({bytes.substr(at + 4, 4), bytes.substr(at + 8, length)});
    at += 12 + length;
  }
  return chunks;
}

const PixelFormat all_formats[] = {PixelFormat::png8,     PixelFormat::png16,     PixelFormat::tiff16,
                                   PixelFormat::exr_half, PixelFormat::exr_float, PixelFormat::exr_float_piz,
                                   PixelFormat::tga8};

const char* extension_of(PixelFormat format) {
  switch (format) {
    case PixelFormat::png8:
    case PixelFormat::png16:
      return ".png";
    case PixelFormat::tiff16:
      return ".tif";
    case PixelFormat::tga8:
      return ".tga";
    default:
      return ".exr";
  }
}

// Whether `read` is what `written` becomes after a trip through `format`.
::testing::AssertionResult survives(PixelFormat format, float written, float read) {
  const auto quantised = [&](float max_value) -> ::testing::AssertionResult {
    const float expected =
        static_cast<float>(std::lround(std::clamp(written, 0.0f, 1.0f) * max_value)) / max_value;
    if (std::fabs(read - expected) <= 1e-7f &&
        std::fabs(read - std::clamp(written, 0.0f, 1.0f)) <= 0.5f / max_value + 1e-7f) {
      return ::testing::AssertionSuccess();
    }
    return ::testing::AssertionFailure()
           << "wrote " << written << ", read " << read << ", expected " << expected;
  };
  switch (format) {
    case PixelFormat::png8:
    case PixelFormat::tga8:
      return quantised(255.0f);
    case PixelFormat::png16:
    case PixelFormat::tiff16:
      return quantised(65535.0f);
    case PixelFormat::exr_half:
      // Half keeps 11 significant bits: relative error at most 2^-11.
      if (std::fabs(read - written) <= std::fabs(written) * 0x1p-11f + 0x1p-25f)
        return ::testing::AssertionSuccess();
      return ::testing::AssertionFailure() << "wrote " << written << ", read " << read << " (half)";
    case PixelFormat::exr_float:
    case PixelFormat::exr_float_piz:
      if (read == written) return ::testing::AssertionSuccess();
      return ::testing::AssertionFailure() << "wrote " << written << ", read " << read << " (float)";
  }
  return ::testing::AssertionFailure() << "unknown format";
}

TEST(ImageFormat, NamesRoundTrip) {
  for (PixelFormat format : all_formats) {
    PixelFormat parsed = PixelFormat::png8;
    ASSERT_TRUE(parse_word(to_string(format), parsed)) << to_string(format);
    EXPECT_EQ(parsed, format);
  }
  EXPECT_STREQ(to_string(PixelFormat::exr_half), "exr-half");
  PixelFormat unused = PixelFormat::png8;
  EXPECT_FALSE(parse_word("png", unused));
  EXPECT_FALSE(parse_word("exr_half", unused));
  EXPECT_FALSE(parse_word("", unused));
}

TEST(ImageFormat, FromPathAndExtensionMatch) {
  PixelFormat format = PixelFormat::png8;
  ASSERT_TRUE(pixel_format_from_path("maps/out.png", format));
  EXPECT_EQ(format, PixelFormat::png16);
  ASSERT_TRUE(pixel_format_from_path("OUT.PNG", format));
  EXPECT_EQ(format, PixelFormat::png16);
  ASSERT_TRUE(pixel_format_from_path("a.tif", format));
  EXPECT_EQ(format, PixelFormat::tiff16);
  ASSERT_TRUE(pixel_format_from_path("a.b.tiff", format));
  EXPECT_EQ(format, PixelFormat::tiff16);
  ASSERT_TRUE(pixel_format_from_path("a.exr", format));
  EXPECT_EQ(format, PixelFormat::exr_float);
  ASSERT_TRUE(pixel_format_from_path("a.TGA", format));
  EXPECT_EQ(format, PixelFormat::tga8);
  EXPECT_TRUE(format_matches_extension(PixelFormat::tga8, "a.tga"));
  EXPECT_FALSE(format_matches_extension(PixelFormat::tga8, "a.png"));
  EXPECT_TRUE(is_8bit(PixelFormat::tga8) && is_8bit(PixelFormat::png8) && !is_8bit(PixelFormat::png16));
  EXPECT_FALSE(pixel_format_from_path("a.jpg", format));
  EXPECT_FALSE(pixel_format_from_path("png", format));
  EXPECT_FALSE(pixel_format_from_path("dir.png/file", format));

  EXPECT_TRUE(format_matches_extension(PixelFormat::png8, "a.png"));
  EXPECT_TRUE(format_matches_extension(PixelFormat::png16, "a.PNG"));
  EXPECT_TRUE(format_matches_extension(PixelFormat::tiff16, "a.tiff"));
  EXPECT_TRUE(format_matches_extension(PixelFormat::exr_half, "a.exr"));
  EXPECT_FALSE(format_matches_extension(PixelFormat::png16, "a.exr"));
  EXPECT_FALSE(format_matches_extension(PixelFormat::exr_float, "a.png"));
  EXPECT_FALSE(format_matches_extension(PixelFormat::tiff16, "a.png"));
  EXPECT_FALSE(format_matches_extension(PixelFormat::png16, "a"));
}

TEST(ImageWrite, RoundTripEveryFormat) {
  TempDir dir;
  for (int channels : {3, 4}) {
    const Image image = make_image(13, 7, channels);
    for (PixelFormat format : all_formats) {
      SCOPED_TRACE(std::string(to_string(format)) + ", " + std::to_string(channels) + " channels");
      const std::string path = dir.file(std::string("rt") + std::to_string(channels) + "_" +
                                        to_string(format) + extension_of(format));
      const Status written = write_image(image, path, format);
      ASSERT_TRUE(written.is_ok()) << written.message();
      Image back;
      const Status read = read_image(path, back);
      ASSERT_TRUE(read.is_ok()) << read.message();
      ASSERT_EQ(back.width, image.width);
      ASSERT_EQ(back.height, image.height);
      ASSERT_EQ(back.channels, image.channels);
      ASSERT_EQ(back.pixels.size(), image.pixels.size());
      for (std::size_t i = 0; i < image.pixels.size(); ++i) {
        ASSERT_TRUE(survives(format, image.pixels[i], back.pixels[i])) << "value " << i;
      }
    }
  }
  // Only the finished files: no temp file left behind.
  for (const std::string& name : list_dir(dir.path())) EXPECT_NE(name[0], '.') << name;
}

TEST(ImageWrite, FilesHoldTheRequestedType) {
  TempDir dir;
  const Image image = make_image(5, 4, 3);
  const struct {
    PixelFormat format;
    const char* file_format;
    const char* data_type;
    const char* compression;  // nullptr: not checked
  } cases[] = {
      {PixelFormat::png8, "png", "uint8", nullptr},
      {PixelFormat::png16, "png", "uint16", nullptr},
      {PixelFormat::tiff16, "tiff", "uint16", "zip"},
      {PixelFormat::exr_half, "openexr", "half", "zip"},
      {PixelFormat::exr_float, "openexr", "float", "zip"},
      {PixelFormat::exr_float_piz, "openexr", "float", "piz"},
      {PixelFormat::tga8, "targa", "uint8", nullptr},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(to_string(c.format));
    const std::string path = dir.file(std::string("t_") + to_string(c.format) + extension_of(c.format));
    ASSERT_TRUE(write_image(image, path, c.format).is_ok());
    ImageFileInfo info;
    const Status status = read_image_info(path, info);
    ASSERT_TRUE(status.is_ok()) << status.message();
    EXPECT_EQ(info.width, 5);
    EXPECT_EQ(info.height, 4);
    EXPECT_EQ(info.channels, 3);
    EXPECT_EQ(info.file_format, c.file_format);
    EXPECT_EQ(info.data_type, c.data_type);
    if (c.compression) {
      EXPECT_EQ(info.compression, c.compression);
    }
  }
}

TEST(ImageWrite, PngHasTheBitDepthAndNoColourChunks) {
  TempDir dir;
  const Image image = make_image(6, 3, 3);
  for (PixelFormat format : {PixelFormat::png8, PixelFormat::png16}) {
    SCOPED_TRACE(to_string(format));
    const std::string path = dir.file(std::string(to_string(format)) + ".png");
    ASSERT_TRUE(write_image(image, path, format).is_ok());
    const std::vector<PngChunk> chunks = png_chunks(path);
    ASSERT_FALSE(chunks.empty());
    ASSERT_EQ(chunks[0].type, "IHDR");
    ASSERT_EQ(chunks[0].data.size(), 13u);
    EXPECT_EQ(static_cast<int>(static_cast<unsigned char>(chunks[0].data[8])),
              format == PixelFormat::png16 ? 16 : 8);
    EXPECT_EQ(static_cast<int>(static_cast<unsigned char>(chunks[0].data[9])), 2);  // colour type: RGB
    EXPECT_EQ(chunks.back().type, "IEND");
    for (const PngChunk& chunk : chunks) {
      // Any of these makes viewers and engines convert the stored values.
      EXPECT_NE(chunk.type, "gAMA");
      EXPECT_NE(chunk.type, "sRGB");
      EXPECT_NE(chunk.type, "iCCP");
      EXPECT_NE(chunk.type, "cHRM");
      EXPECT_NE(chunk.type, "tIME");
    }
  }
}

TEST(ImageWrite, QuantisationRoundsToNearest) {
  TempDir dir;
  Image image;
  image.width = 4;
  image.height = 1;
  image.channels = 3;
  // Just below and above half a step, and out of range both ways.
  image.pixels = {(10 + 0.49f) / 255.0f,
                  (10 + 0.51f) / 255.0f,
                  -0.5f,  //
                  2.0f,
                  254.6f / 255.0f,
                  0.4f / 255.0f,  //
                  0.0f,
                  1.0f,
                  0.5f,  //
                  (100 + 0.49f) / 65535.0f,
                  (100 + 0.51f) / 65535.0f,
                  1.0f};
  const std::string path8 = dir.file("q8.png");
  ASSERT_TRUE(write_image(image, path8, PixelFormat::png8).is_ok());
  Image back;
  ASSERT_TRUE(read_image(path8, back).is_ok());
  const int expected8[] = {10, 11, 0, 255, 255, 0, 0, 255, 128, 0, 0, 255};
  for (int i = 0; i < 12; ++i) EXPECT_EQ(std::lround(back.pixels[i] * 255.0f), expected8[i]) << i;

  const std::string path16 = dir.file("q16.png");
  ASSERT_TRUE(write_image(image, path16, PixelFormat::png16).is_ok());
  ASSERT_TRUE(read_image(path16, back).is_ok());
  EXPECT_EQ(std::lround(back.pixels[9] * 65535.0f), 100);
  EXPECT_EQ(std::lround(back.pixels[10] * 65535.0f), 101);
  EXPECT_EQ(std::lround(back.pixels[8] * 65535.0f), 32768);  // round(0.5 * 65535) = 32767.5 -> 32768
  EXPECT_EQ(std::lround(back.pixels[2] * 65535.0f), 0);
  EXPECT_EQ(std::lround(back.pixels[3] * 65535.0f), 65535);
}

TEST(ImageWrite, AlphaIsStoredAsIs) {
  TempDir dir;
  Image image;
  image.width = 2;
  image.height = 1;
  image.channels = 4;
  image.pixels = {0.8f, 0.6f, 0.4f, 0.25f, 0.2f, 0.9f, 0.7f, 0.0f};
  for (PixelFormat format : all_formats) {
    SCOPED_TRACE(to_string(format));
    const std::string path = dir.file(std::string("alpha_") + to_string(format) + extension_of(format));
    ASSERT_TRUE(write_image(image, path, format).is_ok());
    Image back;
    ASSERT_TRUE(read_image(path, back).is_ok());
    ASSERT_EQ(back.channels, 4);
    // Premultiplying (or un-premultiplying) on either side would move rgb by 4x or zero it.
    for (std::size_t i = 0; i < image.pixels.size(); ++i)
      EXPECT_TRUE(survives(format, image.pixels[i], back.pixels[i]));
  }
}

TEST(ImageWrite, SameImageSameBytesAndNoTimestamp) {
  TempDir dir;
  const Image image = make_image(9, 5, 3);
  const std::regex date_time("[0-9]{4}:[0-9]{2}:[0-9]{2} [0-9]{2}:[0-9]{2}:[0-9]{2}");
  for (PixelFormat format : all_formats) {
    SCOPED_TRACE(to_string(format));
    const std::string a = dir.file(std::string("a_") + to_string(format) + extension_of(format));
    const std::string b = dir.file(std::string("b_") + to_string(format) + extension_of(format));
    ASSERT_TRUE(write_image(image, a, format).is_ok());
    ASSERT_TRUE(write_image(image, b, format).is_ok());
    const std::string bytes = read_bytes(a);
    EXPECT_EQ(bytes, read_bytes(b));
    // A clock time in the file would make regression bakes differ run to run.
    EXPECT_FALSE(std::regex_search(bytes, date_time));
  }
}

TEST(ImageWrite, MissingFolderFailsAndCreatesNothing) {
  TempDir dir;
  const std::string path = dir.file("missing/out.png");
  const Status status = write_image(make_image(2, 2, 3), path, PixelFormat::png16);
  ASSERT_FALSE(status.is_ok());
  EXPECT_EQ(status.code(), StatusCode::io);
  EXPECT_NE(status.message().find(path), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("does not exist"), std::string::npos) << status.message();
  EXPECT_TRUE(list_dir(dir.path()).empty());
}

TEST(ImageWrite, FailedWriteLeavesExistingFileUntouched) {
  TempDir dir;
  const std::string path = dir.file("map.png");
  test::write_text(path, "previous bake");
  // PNG holds at most 4 channels: the write fails.
  const Status status = write_image(make_image(3, 3, 5), path, PixelFormat::png16);
  ASSERT_FALSE(status.is_ok());
  EXPECT_EQ(status.code(), StatusCode::io);
  EXPECT_NE(status.message().find(path), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("channels"), std::string::npos) << status.message();
  EXPECT_EQ(read_bytes(path), "previous bake");
  EXPECT_EQ(list_dir(dir.path()), std::vector<std::string>{"map.png"});
}

TEST(ImageWrite, FailedRenameRemovesTheTempFile) {
  TempDir dir;
  // A non-empty folder where the file should go: everything succeeds but the rename.
  const fs::path blocker = dir.path() / "map.exr";
  fs::create_directory(blocker);
  test::write_text((blocker / "keep.txt").string(), "keep");
  const Status status = write_image(make_image(3, 3, 3), blocker.string(), PixelFormat::exr_half);
  ASSERT_FALSE(status.is_ok());
  EXPECT_EQ(status.code(), StatusCode::io);
  EXPECT_NE(status.message().find(blocker.string()), std::string::npos) << status.message();
  EXPECT_EQ(list_dir(dir.path()), std::vector<std::string>{"map.exr"});
  EXPECT_EQ(list_dir(blocker), std::vector<std::string>{"keep.txt"});
}

TEST(ImageWrite, ReplacesAnExistingFile) {
  TempDir dir;
  const std::string path = dir.file("map.tif");
  test::write_text(path, "previous bake");
  const Image image = make_image(4, 4, 3);
  ASSERT_TRUE(write_image(image, path, PixelFormat::tiff16).is_ok());
  Image back;
  ASSERT_TRUE(read_image(path, back).is_ok());
  EXPECT_EQ(back.width, 4);
  EXPECT_EQ(list_dir(dir.path()), std::vector<std::string>{"map.tif"});
}

TEST(ImageWrite, RelativePathInCurrentFolder) {
  TempDir dir;
  const fs::path previous = fs::current_path();
  fs::current_path(dir.path());
  const Status status = write_image(make_image(2, 2, 3), "plain.png", PixelFormat::png8);
  fs::current_path(previous);
  ASSERT_TRUE(status.is_ok()) << status.message();
  EXPECT_EQ(list_dir(dir.path()), std::vector<std::string>{"plain.png"});
}

TEST(ImageWrite, RejectsFormatNotMatchingExtension) {
  TempDir dir;
  const Image image = make_image(2, 2, 3);
  const struct {
    PixelFormat format;
    const char* name;
  } cases[] = {{PixelFormat::png16, "a.exr"},
               {PixelFormat::exr_half, "a.png"},
               {PixelFormat::tiff16, "a.png"},
               {PixelFormat::png8, "a.tif"},
               {PixelFormat::exr_float, "a"}};
  for (const auto& c : cases) {
    const Status status = write_image(image, dir.file(c.name), c.format);
    ASSERT_FALSE(status.is_ok()) << c.name;
    EXPECT_EQ(status.code(), StatusCode::bad_input);
    EXPECT_NE(status.message().find(dir.file(c.name)), std::string::npos) << status.message();
    EXPECT_NE(status.message().find(to_string(c.format)), std::string::npos) << status.message();
  }
  EXPECT_TRUE(list_dir(dir.path()).empty());
}

TEST(ImageWrite, RejectsNanAndInfinity) {
  TempDir dir;
  Image image = make_image(4, 3, 3);
  image.at(2, 1)[1] = std::numeric_limits<float>::quiet_NaN();
  const std::string path = dir.file("nan.exr");
  Status status = write_image(image, path, PixelFormat::exr_float);
  ASSERT_FALSE(status.is_ok());
  EXPECT_EQ(status.code(), StatusCode::internal);
  EXPECT_NE(status.message().find("NaN at pixel (2, 1) channel 1"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find(path), std::string::npos) << status.message();

  image.at(2, 1)[1] = -std::numeric_limits<float>::infinity();
  status = write_image(image, dir.file("inf.png"), PixelFormat::png16);
  ASSERT_FALSE(status.is_ok());
  EXPECT_EQ(status.code(), StatusCode::internal);
  EXPECT_NE(status.message().find("infinity"), std::string::npos) << status.message();
  EXPECT_TRUE(list_dir(dir.path()).empty());
}

TEST(ImageWrite, RejectsEmptyOrMalformedImage) {
  TempDir dir;
  Image empty;
  Status status = write_image(empty, dir.file("e.png"), PixelFormat::png16);
  ASSERT_FALSE(status.is_ok());
  EXPECT_EQ(status.code(), StatusCode::internal);
  EXPECT_NE(status.message().find("empty image"), std::string::npos) << status.message();

  Image short_buffer = make_image(3, 3, 3);
  short_buffer.pixels.pop_back();
  status = write_image(short_buffer, dir.file("s.png"), PixelFormat::png16);
  ASSERT_FALSE(status.is_ok());
  EXPECT_EQ(status.code(), StatusCode::internal);
  EXPECT_TRUE(list_dir(dir.path()).empty());
}

TEST(ImageRead, MissingOrBadFileNamesThePath) {
  TempDir dir;
  Image image;
  const std::string missing = dir.file("nothing.png");
  Status status = read_image(missing, image);
  ASSERT_FALSE(status.is_ok());
  EXPECT_NE(status.message().find(missing), std::string::npos) << status.message();

  const std::string garbage = dir.file("garbage.exr");
  test::write_text(garbage, "this is not an image");
  status = read_image(garbage, image);
  ASSERT_FALSE(status.is_ok());
  EXPECT_NE(status.message().find(garbage), std::string::npos) << status.message();
  ImageFileInfo info;
  EXPECT_FALSE(read_image_info(garbage, info).is_ok());
}

}  // namespace
}  // namespace nmbake

namespace nmbake {
namespace {

// Tall enough for several independently deflated row groups (image_png.cpp),
// in every channel count and depth; read back by libpng through OpenImageIO,
// which checks every CRC and the combined Adler-32.
TEST(ImagePng, ManyRowGroupsRoundTrip) {
  TempDir dir;
  for (int channels : {1, 2, 3, 4}) {
    for (PixelFormat format : {PixelFormat::png8, PixelFormat::png16}) {
      SCOPED_TRACE(std::string(to_string(format)) + ", " + std::to_string(channels) + " channels");
      const int width = 301;
      const std::size_t row_bytes =
          static_cast<std::size_t>(width) * channels * (format == PixelFormat::png16 ? 2 : 1);
      const int height = static_cast<int>(3 * image_detail::kPngGroupBytes / row_bytes + 5);
      const Image image = make_image(width, height, channels);
      const std::string path = dir.file("groups" + std::to_string(channels) + to_string(format) + ".png");
      ASSERT_TRUE(write_image(image, path, format).is_ok());
      int idat_count = 0;
      for (const PngChunk& chunk : png_chunks(path)) idat_count += chunk.type == "IDAT";
      EXPECT_GE(idat_count, 4);
      Image back;
      const Status read = read_image(path, back);
      ASSERT_TRUE(read.is_ok()) << read.message();
      ASSERT_EQ(back.channels, channels);
      ASSERT_EQ(back.height, height);
      for (std::size_t i = 0; i < image.pixels.size(); ++i) {
        ASSERT_TRUE(survives(format, image.pixels[i], back.pixels[i])) << "value " << i;
      }
    }
  }
}

// The Huffman-only deflate encoder, checked by zlib's inflate: streams of
// every shape decode to their input, and pieces (non-final) concatenate.
std::vector<std::uint8_t> inflate_raw(const std::vector<std::uint8_t>& stream, std::size_t expected) {
  std::vector<std::uint8_t> out(expected + 16);
  z_stream z{};
  EXPECT_EQ(inflateInit2(&z, -15), Z_OK);
  z.next_in = const_cast<std::uint8_t*>(stream.data());
  z.avail_in = static_cast<uInt>(stream.size());
  z.next_out = out.data();
  z.avail_out = static_cast<uInt>(out.size());
  const int result = inflate(&z, Z_FINISH);
  EXPECT_EQ(result, Z_STREAM_END) << (z.msg ? z.msg : "");
  EXPECT_EQ(z.avail_in, 0u) << "bytes after the end of the stream";
  // erase, not resize: GCC 12 at -O1 cannot see that this shrinks (-Wstringop-overflow).
  out.erase(out.end() - static_cast<std::ptrdiff_t>(z.avail_out), out.end());
  inflateEnd(&z);
  return out;
}

TEST(DeflateHuffman, InflatesToTheInput) {
  std::vector<std::vector<std::uint8_t>> inputs;
  inputs.emplace_back();                         // empty
  inputs.emplace_back(1, std::uint8_t{7});       // one byte
  inputs.emplace_back(200000, std::uint8_t{0});  // one value only, several blocks
  std::vector<std::uint8_t> all_values(256 * 1000), noise(300001), skewed(150000);
  for (std::size_t i = 0; i < all_values.size(); ++i) all_values[i] = static_cast<std::uint8_t>(i);
  std::uint32_t h = 12345;
  for (auto& b : noise) b = static_cast<std::uint8_t>((h = h * 1664525u + 1013904223u) >> 24);
  // Fibonacci-like counts: an unlimited Huffman code would need ~25 bits.
  std::size_t at = 0;
  std::uint64_t f0 = 1, f1 = 1;
  for (int v = 0; v < 26 && at < skewed.size(); ++v) {
    for (std::uint64_t k = 0; k < f0 && at < skewed.size(); ++k) skewed[at++] = static_cast<std::uint8_t>(v);
    const std::uint64_t f2 = f0 + f1;
    f0 = f1, f1 = f2;
  }
  inputs.push_back(all_values), inputs.push_back(noise), inputs.push_back(skewed);
  for (std::size_t n = 0; n < inputs.size(); ++n) {
    SCOPED_TRACE("input " + std::to_string(n));
    std::vector<std::uint8_t> stream;
    image_detail::deflate_huffman(inputs[n].data(), inputs[n].size(), true, stream);
    EXPECT_EQ(inflate_raw(stream, inputs[n].size()), inputs[n]);
    // The same input cut into non-final pieces and a final one.
    std::vector<std::uint8_t> pieces;
    const std::size_t cut = inputs[n].size() / 3;
    image_detail::deflate_huffman(inputs[n].data(), cut, false, pieces);
    image_detail::deflate_huffman(inputs[n].data() + cut, cut, false, pieces);
    image_detail::deflate_huffman(inputs[n].data() + 2 * cut, inputs[n].size() - 2 * cut, true, pieces);
    EXPECT_EQ(inflate_raw(pieces, inputs[n].size()), inputs[n]);
  }
}

TEST(DeflateHuffman, CodeLengthsAreLimitedAndComplete) {
  std::vector<std::uint32_t> freq(257, 0);
  std::uint32_t a = 1, b = 1;
  for (int s = 0; s < 40; ++s) {  // Fibonacci counts: the unlimited code is 39 bits deep
    freq[s] = a;
    const std::uint32_t c = a + b;
    a = b, b = c;
  }
  for (int max_bits : {7, 15}) {
    const std::vector<std::uint8_t> lengths = image_detail::huffman_lengths(freq, max_bits);
    double kraft = 0.0;
    for (std::size_t s = 0; s < freq.size(); ++s) {
      if (freq[s] == 0) {
        EXPECT_EQ(lengths[s], 0) << s;
        continue;
      }
      EXPECT_GE(lengths[s], 1) << s;
      EXPECT_LE(lengths[s], max_bits) << s;
      kraft += std::ldexp(1.0, -lengths[s]);
    }
    EXPECT_DOUBLE_EQ(kraft, 1.0) << "a complete prefix code";
  }
  // One symbol used: a second one-bit code completes the code.
  std::vector<std::uint32_t> one(19, 0);
  one[5] = 10;
  const std::vector<std::uint8_t> lengths = image_detail::huffman_lengths(one, 7);
  EXPECT_EQ(lengths[5], 1);
  EXPECT_EQ(lengths[0], 1);
}

TEST(ImagePng, SameBytesWithOneThreadOrAll) {
  TempDir dir;
  const Image image = make_image(512, 700, 3);
  const std::vector<std::uint8_t> all = image_detail::encode_png(image, 16);
  std::vector<std::uint8_t> one;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = image_detail::encode_png(image, 16);
  }
  EXPECT_EQ(all, one);
}

// Ordered dithering of 8-bit outputs: a flat 76.5-step grey becomes 76s
// and 77s in about equal shares (rounding makes it all 77s), so the mean is kept;
// every texel stays within one step; the pattern is a function of the
// texel's index, the same in PNG and TGA, and in a row group of its own.
TEST(ImageDither, KeepsTheMeanWithinOneStep) {
  TempDir dir;
  Image flat;
  flat.width = 64;
  flat.height = 40;
  flat.channels = 3;
  flat.pixels.assign(static_cast<std::size_t>(flat.width) * flat.height * 3, 76.5f / 255.0f);
  for (const PixelFormat format : {PixelFormat::png8, PixelFormat::tga8}) {
    SCOPED_TRACE(to_string(format));
    const std::string path = dir.file(std::string("flat") + extension_of(format));
    const std::string rounded = dir.file(std::string("round") + extension_of(format));
    ASSERT_TRUE(write_image(flat, path, format, WriteOptions{true}).is_ok());
    ASSERT_TRUE(write_image(flat, rounded, format).is_ok());
    Image back, round_back;
    ASSERT_TRUE(read_image(path, back).is_ok());
    ASSERT_TRUE(read_image(rounded, round_back).is_ok());
    double sum = 0.0;
    int low = 0, high = 0;
    for (std::size_t i = 0; i < back.pixels.size(); ++i) {
      const long q = std::lround(back.pixels[i] * 255.0f);
      ASSERT_TRUE(q == 76 || q == 77) << q;
      (q == 76 ? low : high) += 1;
      sum += static_cast<double>(q);
      EXPECT_EQ(std::lround(round_back.pixels[i] * 255.0f), 77);
    }
    EXPECT_NEAR(static_cast<double>(low) / (low + high), 0.5, 0.01);
    EXPECT_NEAR(sum / static_cast<double>(back.pixels.size()), 76.5, 0.01);
    // Channels do not step together: some texel has 76 in one channel and 77 in another.
    bool mixed = false;
    for (std::size_t t = 0; t < back.pixels.size() / 3 && !mixed; ++t) {
      mixed = std::lround(back.pixels[3 * t] * 255.0f) != std::lround(back.pixels[3 * t + 1] * 255.0f);
    }
    EXPECT_TRUE(mixed);
  }
  // Exact steps stay exact: k / 255 is k with or without the pattern.
  Image steps = make_image(256, 3, 3);
  for (std::size_t i = 0; i < steps.pixels.size(); ++i)
    steps.pixels[i] = static_cast<float>(i % 256) / 255.0f;
  ASSERT_TRUE(write_image(steps, dir.file("steps.png"), PixelFormat::png8, WriteOptions{true}).is_ok());
  Image back;
  ASSERT_TRUE(read_image(dir.file("steps.png"), back).is_ok());
  for (std::size_t i = 0; i < back.pixels.size(); ++i)
    ASSERT_EQ(std::lround(back.pixels[i] * 255.0f), static_cast<long>(i % 256));
  // The same pixels in PNG and TGA.
  const Image image = make_image(37, 29, 3);
  ASSERT_TRUE(write_image(image, dir.file("d.png"), PixelFormat::png8, WriteOptions{true}).is_ok());
  ASSERT_TRUE(write_image(image, dir.file("d.tga"), PixelFormat::tga8, WriteOptions{true}).is_ok());
  Image a, b;
  ASSERT_TRUE(read_image(dir.file("d.png"), a).is_ok());
  ASSERT_TRUE(read_image(dir.file("d.tga"), b).is_ok());
  EXPECT_EQ(a.pixels, b.pixels);
}

TEST(ImageDither, SameBytesWithOneThreadOrAllAndNoTimestampInTga) {
  TempDir dir;
  const Image image = make_image(512, 700, 3);  // several PNG row groups
  const std::vector<std::uint8_t> all = image_detail::encode_png(image, 8, true);
  std::vector<std::uint8_t> one;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = image_detail::encode_png(image, 8, true);
  }
  EXPECT_EQ(all, one);
  EXPECT_NE(all, image_detail::encode_png(image, 8, false));
  ASSERT_TRUE(write_image(image, dir.file("a.tga"), PixelFormat::tga8, WriteOptions{true}).is_ok());
  ASSERT_TRUE(write_image(image, dir.file("b.tga"), PixelFormat::tga8, WriteOptions{true}).is_ok());
  EXPECT_EQ(read_bytes(dir.file("a.tga")), read_bytes(dir.file("b.tga")));
}

// Our EXR writer against OpenEXR itself (read back through OpenImageIO) and
// Imath's half: many chunks with a partial last one, every channel count,
// float samples bit for bit, half ones as Imath rounds them, and chunks of
// noise, which do not shrink and are stored raw.
TEST(ImageExr, ManyChunksRoundTripBitExact) {
  TempDir dir;
  for (int channels : {1, 2, 3, 4}) {
    for (const bool noise : {false, true}) {
      Image image = make_image(301, 5 * image_detail::kExrZipLines + 7, channels);
      // A smooth map, and noise.
      for (std::size_t i = 0; i < image.pixels.size(); ++i) {
        const std::size_t texel = i / channels, x = texel % 301, y = texel / 301;
        image.pixels[i] = 0.5f + 0.4f * std::sin(0.05f * x + i % channels) * std::cos(0.07f * y);
      }
      if (noise) {
        std::uint32_t state = 99u;
        for (float& v : image.pixels) {
          state = state * 1664525u + 1013904223u;
          v = static_cast<float>(state >> 8) / 16777216.0f;
        }
      }
      for (PixelFormat format : {PixelFormat::exr_float, PixelFormat::exr_half}) {
        SCOPED_TRACE(std::string(to_string(format)) + ", " + std::to_string(channels) + " channels" +
                     (noise ? ", noise" : ""));
        const std::string path = dir.file("chunks" + std::to_string(channels) + to_string(format) + ".exr");
        ASSERT_TRUE(write_image(image, path, format).is_ok());
        Image back;
        const Status read = read_image(path, back);
        ASSERT_TRUE(read.is_ok()) << read.message();
        ASSERT_EQ(back.channels, channels);
        ASSERT_EQ(back.height, image.height);
        ASSERT_EQ(back.pixels.size(), image.pixels.size());
        for (std::size_t i = 0; i < image.pixels.size(); ++i) {
          const float expected = format == PixelFormat::exr_float
                                     ? image.pixels[i]
                                     : static_cast<float>(Imath::half(image.pixels[i]));
          ASSERT_EQ(std::memcmp(&back.pixels[i], &expected, sizeof expected), 0)
              << "value " << i << ": wrote " << image.pixels[i] << ", read " << back.pixels[i];
        }
        const std::uintmax_t raw_bytes = image.pixels.size() * (format == PixelFormat::exr_float ? 4u : 2u);
        // Half samples of a smooth map shrink; float noise is stored raw
        // (ZIP's byte deltas leave little for Huffman codes in float data).
        if (!noise && format == PixelFormat::exr_half) {
          EXPECT_LT(fs::file_size(path), raw_bytes);
        }
        if (noise && format == PixelFormat::exr_float) {
          EXPECT_GT(fs::file_size(path), raw_bytes);
        }
      }
    }
  }
}

TEST(ImageExr, FloatToHalfMatchesImath) {
  const auto check = [](float f) {
    const std::uint16_t ours = image_detail::float_to_half(f);
    if (std::isnan(f)) {
      EXPECT_EQ(ours & 0x7c00u, 0x7c00u);
      EXPECT_NE(ours & 0x3ffu, 0u) << "NaN must stay NaN";
      return;
    }
    ASSERT_EQ(ours, Imath::half(f).bits()) << f;
  };
  // Around every finite half: the value, the midpoint to the next one (ties
  // go to even) and a float step either side of it, both signs.
  for (std::uint32_t h = 0; h < 0x7c00u; ++h) {
    Imath::half lo, hi;
    lo.setBits(static_cast<std::uint16_t>(h));
    hi.setBits(static_cast<std::uint16_t>(h + 1));
    const float a = static_cast<float>(lo), b = static_cast<float>(hi);
    const float mid = a + (b - a) / 2.0f;
    for (const float f : {a, mid, std::nextafter(mid, 0.0f), std::nextafter(mid, 1e9f), b}) {
      check(f);
      check(-f);
    }
  }
  // A sweep of bit patterns, and the specials.
  for (std::uint64_t bits = 0; bits <= 0xffffffffull; bits += 4099) {
    const std::uint32_t b = static_cast<std::uint32_t>(bits);
    float f;
    std::memcpy(&f, &b, sizeof f);
    check(f);
  }
  for (const float f :
       {0.0f, -0.0f, 65504.0f, 65519.99f, 65520.0f, 1e30f, std::numeric_limits<float>::infinity(),
        -std::numeric_limits<float>::infinity(), std::numeric_limits<float>::quiet_NaN(),
        std::numeric_limits<float>::denorm_min(), 5.96e-8f, 2.98e-8f, 2.99e-8f}) {
    check(f);
  }
}

TEST(ImageExr, SameBytesWithOneThreadOrAll) {
  const Image image = make_image(512, 300, 3);
  for (const bool half : {false, true}) {
    const std::vector<std::uint8_t> all = image_detail::encode_exr(image, half);
    std::vector<std::uint8_t> one;
    {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
      one = image_detail::encode_exr(image, half);
    }
    EXPECT_EQ(all, one);
  }
}

// The quantiser rounds in float (vectorised) what it rounded in double:
// round(p) of the float p = clamp(v) * max, for every 8- and 16-bit step's
// neighbourhood and a sweep of random values.
TEST(ImageWrite, QuantiseIsRoundOfTheFloatProduct) {
  const auto reference = [](float v, float max_value) {
    const float p = std::clamp(v, 0.0f, 1.0f) * max_value;
    return static_cast<std::uint32_t>(std::floor(static_cast<double>(p) + 0.5));
  };
  for (const float max_value : {255.0f, 65535.0f}) {
    for (int k = 0; k <= static_cast<int>(max_value); ++k) {
      // Values whose product lies around k + 0.5 and k, a few ulps either way.
      for (const float target : {static_cast<float>(k) + 0.5f, static_cast<float>(k)}) {
        float v = target / max_value;
        for (int step = 0; step < 4; ++step) v = std::nextafter(v, 0.0f);
        for (int step = 0; step < 9; ++step, v = std::nextafter(v, 2.0f)) {
          ASSERT_EQ(detail::quantise(v, max_value), reference(v, max_value)) << v << " " << max_value;
        }
      }
    }
    std::uint32_t seed = 3;
    for (int i = 0; i < 1000000; ++i) {
      seed = seed * 1664525u + 1013904223u;
      const float v = static_cast<float>(seed >> 8) * 0x1p-24f * 1.2f - 0.1f;
      ASSERT_EQ(detail::quantise(v, max_value), reference(v, max_value)) << v;
    }
  }
}

// The dithered quantiser four lanes at a time (quantise_dithered4_8bit, what the
// PNG writer runs) gives quantise_dithered()'s integers: for values around
// every step, out of range and at far texels; and a PNG of 1 to 4 channels
// whose widths leave 0 to 3 texels for the scalar tail stores them.
TEST(ImageWrite, DitheredLanesAreTheScalarDither) {
  std::uint32_t seed = 11;
  const auto next = [&] { return seed = seed * 1664525u + 1013904223u; };
  for (int i = 0; i < 400000; ++i) {
    float v[4];
    for (float& x : v) {
      // Mostly near a step (where the threshold decides), some anywhere.
      const std::uint32_t r = next();
      x = (r & 3) ? (static_cast<float>((r >> 2) % 256) + static_cast<float>(next() >> 8) * 0x1p-24f - 0.5f) /
                        255.0f
                  : static_cast<float>(r >> 8) * 0x1p-24f * 1.4f - 0.2f;
    }
    const std::uint32_t x = next() % 70000, y = next() % 70000, c = next() % 4;
    std::uint8_t lanes[4];
    detail::quantise_dithered4_8bit(v, x, y, c, lanes);
    for (std::uint32_t k = 0; k < 4; ++k) {
      ASSERT_EQ(std::uint32_t{lanes[k]}, detail::quantise_dithered(v[k], 255.0f, x + k, y, c))
          << v[k] << " at " << x + k << "," << y;
    }
  }
  TempDir dir;
  for (int channels = 1; channels <= 4; ++channels) {
    for (const int width : {1, 3, 4, 7, 66}) {
      SCOPED_TRACE(std::to_string(channels) + " channels, width " + std::to_string(width));
      Image image = make_image(width, 9, channels);
      for (float& p : image.pixels) p = static_cast<float>(next() >> 8) * 0x1p-24f;
      WriteOptions options;
      options.dither = true;
      ASSERT_TRUE(write_image(image, dir.file("d.png"), PixelFormat::png8, options).is_ok());
      Image back;
      ASSERT_TRUE(read_image(dir.file("d.png"), back).is_ok());
      ASSERT_EQ(back.pixels.size(), image.pixels.size());
      for (int yy = 0, i = 0; yy < 9; ++yy) {
        for (int xx = 0; xx < width; ++xx) {
          for (int c = 0; c < channels; ++c, ++i) {
            const std::uint32_t q = detail::quantise_dithered(image.pixels[i], 255.0f, xx, yy, c);
            ASSERT_EQ(std::lround(back.pixels[i] * 255.0f), static_cast<long>(q))
                << xx << "," << yy << " c" << c;
          }
        }
      }
    }
  }
}

// WriteOptions::scale and offset: integer files store v * scale + offset,
// the same bytes as the mapped image written plainly; float files store v.
TEST(ImageWrite, IntegerFilesStoreTheMappedValues) {
  TempDir dir;
  Image raw = make_image(67, 43, 1);
  for (std::size_t i = 0; i < raw.pixels.size(); ++i)
    raw.pixels[i] = 3.0f * std::sin(0.37f * static_cast<float>(i));
  const float scale = 0.5f / 3.5f, offset = 0.5f;  // some values clamp: range 3.5 < |v| never, 3 < 3.5
  Image mapped = raw;
  for (float& v : mapped.pixels) v = v * scale + offset;
  for (const PixelFormat format :
       {PixelFormat::png8, PixelFormat::png16, PixelFormat::tiff16, PixelFormat::tga8}) {
    for (const bool dither : {false, true}) {
      SCOPED_TRACE(std::string(to_string(format)) + (dither ? " dithered" : ""));
      WriteOptions options;
      options.dither = dither;
      const std::string plain = dir.file(std::string("plain") + extension_of(format));
      ASSERT_TRUE(write_image(mapped, plain, format, options).is_ok());
      options.scale = scale;
      options.offset = offset;
      const std::string through = dir.file(std::string("mapped") + extension_of(format));
      ASSERT_TRUE(write_image(raw, through, format, options).is_ok());
      EXPECT_TRUE(read_bytes(plain) == read_bytes(through));
    }
  }
  WriteOptions options;
  options.scale = scale;
  options.offset = offset;
  ASSERT_TRUE(write_image(raw, dir.file("mapped.exr"), PixelFormat::exr_float, options).is_ok());
  Image back;
  ASSERT_TRUE(read_image(dir.file("mapped.exr"), back).is_ok());
  EXPECT_EQ(back.pixels, raw.pixels);
}

}  // namespace
}  // namespace nmbake
