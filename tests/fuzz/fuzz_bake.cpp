// The whole bake (load, unwrap when the low mesh has no UVs, normals,
// tangents, raster, distances, trace, encode, dilate, write) on tiny meshes
// made from the fuzzer's bytes: a 16 x 16 map, 1 or 4 samples. Byte 0 holds
// the options, bytes 1-4 the vertex and triangle counts, then one byte per
// coordinate (a few byte values stand for the awkward ones: 0, a denormal,
// 1e8, and 5e29, which the bake must refuse), one per index and UV.
#include <tbb/global_control.h>

#include <string>

#include "fuzz_util.hpp"
#include "nmbake/bake.hpp"

namespace {

struct Bytes {
  const std::uint8_t* data;
  std::size_t size, next = 0;
  std::uint8_t take() { return next < size ? data[next++] : 0; }
};

float coordinate(std::uint8_t b) {
  switch (b) {
    case 255:
      return 5e29f;
    case 254:
      return 1e8f;
    case 253:
      return 1e-40f;
    case 252:
      return 0.0f;
    default:
      return (static_cast<float>(b) - 126.0f) / 32.0f;
  }
}

std::string obj(Bytes& in, int vertices, int triangles, bool uvs) {
  std::string text;
  for (int v = 0; v < vertices; ++v) {
    text += "v";
    for (int k = 0; k < 3; ++k) text += " " + std::to_string(coordinate(in.take()));
    text += "\n";
    if (uvs)
      text += "vt " + std::to_string(in.take() / 255.0f) + " " + std::to_string(in.take() / 255.0f) + "\n";
  }
  for (int t = 0; t < triangles; ++t) {
    text += "f";
    for (int k = 0; k < 3; ++k) {
      const std::string i = std::to_string(1 + in.take() % vertices);
      text += " " + (uvs ? i + "/" + i : i);
    }
    text += "\n";
  }
  return text;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // One thread: two cores are shared, and the fuzzer wants executions.
  static const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  Bytes in{data, size};
  const std::uint8_t flags = in.take();
  const int low_vertices = 3 + in.take() % 6, low_triangles = 1 + in.take() % 6;
  const int high_vertices = 3 + in.take() % 10, high_triangles = 1 + in.take() % 12;
  const std::string low_text = obj(in, low_vertices, low_triangles, (flags & 1) != 0);
  const std::string high_text = obj(in, high_vertices, high_triangles, false);
  const nmbake::fuzz::InputFile low(reinterpret_cast<const std::uint8_t*>(low_text.data()), low_text.size(),
                                    "low.obj");
  const nmbake::fuzz::InputFile high(reinterpret_cast<const std::uint8_t*>(high_text.data()),
                                     high_text.size(), "high.obj");
  nmbake::BakeOptions o;
  o.low_path = low.path();
  o.high_paths = {high.path()};
  const std::string map = (nmbake::fuzz::scratch_folder() / "map.png").string();
  o.outputs = {{map, nmbake::PixelFormat::png16}};
  o.width = o.height = 16;
  o.samples = (flags & 2) ? 4 : 1;
  o.rays.hit = (flags & 4) ? nmbake::HitRule::nearest : nmbake::HitRule::first;
  o.rays.cage_mode = (flags & 8) ? nmbake::CageMode::interpolated : nmbake::CageMode::averaged;
  o.encode.space = (flags & 16) ? nmbake::NormalSpace::object : nmbake::NormalSpace::tangent;
  o.padding = 2;
  o.unwrap_gutter = 1;
  if (flags & 32) {
    o.rays.front = {nmbake::Distance::Kind::percent, static_cast<float>(in.take())};
    o.rays.back = {nmbake::Distance::Kind::absolute, coordinate(in.take())};
    if (o.rays.back.value < 0.0f) o.rays.back.value = -o.rays.back.value;
  }
  nmbake::BakeReport report;
  if (nmbake::bake(o, report).is_ok()) {
    std::remove(map.c_str());
    if (report.unwrapped) std::remove(report.unwrapped_low_path.c_str());
  }
  return 0;
}
