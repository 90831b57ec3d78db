// The high mesh's textures (textures.hpp): read, decoded, mip-mapped, sampled.
#include "nmbake/textures.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <glm/common.hpp>
#include <string>
#include <vector>

#include "base/huge_pages.hpp"
#include "nmbake/udim.hpp"

namespace nmbake {
namespace {

namespace fs = std::filesystem;

// 2x2 box filter; an odd last row or column folds into the one before it
// (its weight shared), so every texel of the finer level counts.
Image half_level(const Image& fine) {
  Image coarse;
  coarse.width = std::max(1, fine.width / 2);
  coarse.height = std::max(1, fine.height / 2);
  coarse.channels = fine.channels;
  detail::size_output(coarse.pixels,
                      static_cast<std::size_t>(coarse.width) * coarse.height * coarse.channels);
  const int c = fine.channels;
  tbb::parallel_for(tbb::blocked_range<int>(0, coarse.height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y != rows.end(); ++y) {
      const int y0 = std::min(2 * y, fine.height - 1);
      const int y1 = (y == coarse.height - 1) ? fine.height - 1 : std::min(2 * y + 1, fine.height - 1);
      for (int x = 0; x < coarse.width; ++x) {
        const int x0 = std::min(2 * x, fine.width - 1);
        const int x1 = (x == coarse.width - 1) ? fine.width - 1 : std::min(2 * x + 1, fine.width - 1);
        float* out = coarse.at(x, y);
        // The texels [x0, x1] x [y0, y1] (2x2, or 3 wide at an odd edge).
        int count = 0;
        for (int yy = y0; yy <= y1; ++yy) {
          for (int xx = x0; xx <= x1; ++xx) {
            const float* in = fine.at(xx, yy);
            for (int k = 0; k < c; ++k) out[k] += in[k];
            ++count;
          }
        }
        for (int k = 0; k < c; ++k) out[k] /= static_cast<float>(count);
      }
    }
  });
  return coarse;
}

int wrap_index(int i, int n, TextureWrap wrap) {
  if (i >= 0 && i < n) return i;  // inside: every mode leaves it (no division on the common path)
  switch (wrap) {
    case TextureWrap::clamp:
      return std::clamp(i, 0, n - 1);
    case TextureWrap::mirror: {
      const int period = 2 * n;
      int m = i % period;
      if (m < 0) m += period;
      return m < n ? m : period - 1 - m;
    }
    case TextureWrap::repeat:
    default: {
      int m = i % n;
      return m < 0 ? m + n : m;
    }
  }
}

// A row-major image as a block-ordered level of RGBA texels.
MipLevel to_level(const Image& image) {
  MipLevel level;
  level.width = image.width;
  level.height = image.height;
  level.blocks_x = (image.width + 3) / 4;
  const int blocks_y = (image.height + 3) / 4;
  const int c = image.channels;
  level.channels = c == 1 ? 1 : 4;
  detail::size_output(level.data, static_cast<std::size_t>(level.blocks_x) * blocks_y * 16 * level.channels);
  tbb::parallel_for(tbb::blocked_range<int>(0, image.height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y != rows.end(); ++y) {
      for (int x = 0; x < image.width; ++x) {
        const float* p = image.at(x, y);
        glm::vec4 v;
        switch (c) {
          case 1:
            v = glm::vec4(p[0], p[0], p[0], 1.0f);
            break;
          case 2:
            v = glm::vec4(p[0], p[0], p[0], p[1]);
            break;
          case 3:
            v = glm::vec4(p[0], p[1], p[2], 1.0f);
            break;
          default:
            v = glm::vec4(p[0], p[1], p[2], p[3]);
            break;
        }
        float* out = &level.data[level.index(x, y)];
        if (level.channels == 1) {
          out[0] = v.r;
        } else {
          out[0] = v.r;
          out[1] = v.g;
          out[2] = v.b;
          out[3] = v.a;
        }
      }
    }
  });
  return level;
}

// Bilinear at (x, y) in the level's texel units (texel centres at + 0.5),
// y from the top.
glm::vec4 bilinear(const MipLevel& level, float x, float y, const TextureRef& ref) {
  x -= 0.5f;
  y -= 0.5f;
  const float fx = std::floor(x), fy = std::floor(y);
  const float ax = x - fx, ay = y - fy;
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
  const int x0 = wrap_index(ix, level.width, ref.wrap_u), x1 = wrap_index(ix + 1, level.width, ref.wrap_u);
  const int y0 = wrap_index(iy, level.height, ref.wrap_v), y1 = wrap_index(iy + 1, level.height, ref.wrap_v);
  const glm::vec4 top = level.at(x0, y0) * (1.0f - ax) + level.at(x1, y0) * ax;
  const glm::vec4 bottom = level.at(x0, y1) * (1.0f - ax) + level.at(x1, y1) * ax;
  return top * (1.0f - ay) + bottom * ay;
}

// The tiles of a <UDIM> path that exist: every file in its folder whose name
// is the pattern's with a tile number 1001..1999 in place of the token.
std::vector<std::pair<int, std::string>> udim_files(const std::string& pattern) {
  std::vector<std::pair<int, std::string>> out;
  for (int tile = 1001; tile <= 1999; ++tile) {
    const std::string path = udim_path(pattern, tile);
    std::error_code ec;
    if (fs::exists(path, ec)) out.emplace_back(tile, path);
  }
  return out;
}

// Raw 8-bit RGBA texels (EmbeddedImage with a width) as an image; rows
// from the top, as files have them.
Status raw_texels(const EmbeddedImage& embedded, Image& image) {
  const std::size_t texels =
      static_cast<std::size_t>(embedded.width) * static_cast<std::size_t>(embedded.height);
  if (embedded.width <= 0 || embedded.height <= 0 || embedded.width > kMaxReadSide ||
      embedded.height > kMaxReadSide || embedded.bytes.size() != texels * 4) {
    return Status::bad_input("its " + std::to_string(embedded.width) + "x" + std::to_string(embedded.height) +
                             " texels do not match its " + std::to_string(embedded.bytes.size()) + " bytes");
  }
  image.width = embedded.width;
  image.height = embedded.height;
  image.channels = 4;
  image.pixels.resize(texels * 4);
  for (std::size_t i = 0; i < texels * 4; ++i)
    image.pixels[i] = static_cast<float>(embedded.bytes[i]) / 255.0f;
  return Status::ok();
}

// The image of a file, or of an embedded image (`embedded` non-null), with
// colour decoded to linear light when `color`.
Status read_texture_image(const std::string& path, const EmbeddedImage* embedded, bool color, Image& image) {
  if (embedded == nullptr) {
    NMBAKE_TRY(read_image(path, image));
  } else if (embedded->width > 0) {
    NMBAKE_TRY(raw_texels(*embedded, image));
  } else {
    NMBAKE_TRY(
        read_image_memory(path, embedded->bytes.data(), embedded->bytes.size(), embedded->format, image));
  }
  if (color) {
    const int c = image.channels;
    const int color_channels = c >= 3 ? 3 : (c == 2 ? 1 : c);
    float table[256];
    for (int q = 0; q < 256; ++q) table[q] = srgb_to_linear(static_cast<float>(q) / 255.0f);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, image.pixels.size() / c),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i) {
                          for (int k = 0; k < color_channels; ++k) {
                            float& v = image.pixels[i * c + k];
                            // An 8-bit file's values are k / 255 (to float rounding:
                            // OpenImageIO multiplies by 1 / 255): from the table.
                            const float step = v * 255.0f + 0.5f;
                            const auto q = static_cast<int>(step);
                            const bool eight_bit = v >= 0.0f && v <= 1.0f &&
                                                   std::abs(static_cast<float>(q) / 255.0f - v) <= 1e-7f;
                            v = eight_bit ? table[static_cast<std::size_t>(q)] : srgb_to_linear(v);
                          }
                        }
                      });
  }
  return Status::ok();
}

}  // namespace

MipTexture make_mip_texture(Image image) {
  MipTexture mip;
  mip.channels = image.channels;
  // Built row-major, stored in blocks (in 2 MB pages: size_output).
  mip.levels.push_back(to_level(image));
  while (image.width > 1 || image.height > 1) {
    image = half_level(image);
    mip.levels.push_back(to_level(image));
  }
  return mip;
}

glm::vec4 sample_texture(const LoadedTexture& texture, const TextureRef& ref, glm::vec2 uv, float footprint,
                         bool& tile_missing) {
  // To the image's top-left convention, then the texture's transform
  // (KHR_texture_transform: offset + rotation * (scale * uv)).
  glm::vec2 t(uv.x, 1.0f - uv.y);
  if (ref.scale != glm::vec2(1.0f) || ref.rotation != 0.0f || ref.offset != glm::vec2(0.0f)) {
    const float c = std::cos(ref.rotation), s = std::sin(ref.rotation);
    const glm::vec2 scaled = t * ref.scale;
    t = glm::vec2(c * scaled.x + s * scaled.y, -s * scaled.x + c * scaled.y) + ref.offset;
  }
  // Far outside any UV range a float has no fraction left; keep indices in int.
  t = glm::clamp(t, glm::vec2(-1e6f), glm::vec2(1e6f));
  const MipTexture* mip = nullptr;
  if (texture.udim()) {
    const float u_floor = std::floor(t.x), v_floor = std::floor(1.0f - t.y);
    const int tile = 1001 + static_cast<int>(u_floor) + 10 * static_cast<int>(v_floor);
    const auto it = texture.tiles.find(tile);
    if (u_floor < 0.0f || u_floor > 9.0f || v_floor < 0.0f || it == texture.tiles.end()) {
      tile_missing = true;
      return glm::vec4(0.0f);
    }
    mip = &it->second;
    t = glm::vec2(t.x - u_floor, 1.0f - ((1.0f - t.y) - v_floor));
  } else {
    mip = &texture.tiles.begin()->second;
  }
  const MipLevel& base = mip->levels.front();
  const float scale = std::max(std::abs(ref.scale.x), std::abs(ref.scale.y));
  const float width = footprint * scale * static_cast<float>(std::max(base.width, base.height));
  const float last = static_cast<float>(mip->levels.size() - 1);
  const float lod = std::clamp(width > 1.0f ? std::log2(width) : 0.0f, 0.0f, last);
  const int l0 = static_cast<int>(lod);
  const float a = lod - static_cast<float>(l0);
  const auto at_level = [&](int l) {
    const MipLevel& level = mip->levels[static_cast<std::size_t>(l)];
    return bilinear(level, t.x * static_cast<float>(level.width), t.y * static_cast<float>(level.height),
                    ref);
  };
  const glm::vec4 fine = at_level(l0);
  if (a <= 0.0f || l0 + 1 >= static_cast<int>(mip->levels.size())) return fine;
  return fine * (1.0f - a) + at_level(l0 + 1) * a;
}

float texture_channel(const glm::vec4& value, int channel, bool has_alpha) {
  if (channel >= 0 && channel <= 2) return value[channel];
  if (channel == 3 && has_alpha) return value.a;
  return 0.2126f * value.r + 0.7152f * value.g + 0.0722f * value.b;
}

Status load_material_textures(const Mesh& high, const std::string& high_path, const TextureNeeds& needs,
                              TextureSet& out) {
  const auto begin = std::chrono::steady_clock::now();
  out = TextureSet{};
  out.by_material.resize(high.material_defs.size());
  // Which files: one read per file and colour space (the alpha of a colour
  // texture is linear, so opacity from the base colour's alpha shares it).
  struct Read {
    std::size_t texture;
    int tile;
    std::string path, where;
    const EmbeddedImage* embedded;  // or null: the file `path`
  };
  std::vector<Read> reads;
  const auto plan = [&](const Material& m, const char* attribute, const TextureRef& ref, bool color,
                        int& index) -> Status {
    if (ref.empty()) return Status::ok();
    const std::string where =
        high_path + ": material '" + printable_text(m.name) + "', " + attribute + " texture";
    if (!ref.problem.empty()) return Status::bad_input(where + ": " + ref.problem);
    if (ref.embedded >= 0 && static_cast<std::size_t>(ref.embedded) >= high.embedded_images.size()) {
      return Status::internal(where + ": embedded image " + std::to_string(ref.embedded) +
                              " is not among the mesh's " + std::to_string(high.embedded_images.size()));
    }
    for (std::size_t i = 0; i < out.textures.size(); ++i) {
      const bool alpha_only = !color && ref.channel == 3;
      if (out.textures[i].path == ref.path && out.textures[i].embedded == ref.embedded &&
          (out.textures[i].color == color || alpha_only)) {
        index = static_cast<int>(i);
        return Status::ok();
      }
    }
    if (ref.embedded >= 0) {
      // An embedded image: one tile, named by its index in messages.
      index = static_cast<int>(out.textures.size());
      out.textures.emplace_back();
      out.textures.back().embedded = ref.embedded;
      out.textures.back().color = color;
      reads.push_back(Read{static_cast<std::size_t>(index), 0,
                           "embedded image " + std::to_string(ref.embedded), where,
                           &high.embedded_images[static_cast<std::size_t>(ref.embedded)]});
      return Status::ok();
    }
    std::vector<std::pair<int, std::string>> files;
    if (has_udim_token(ref.path)) {
      files = udim_files(ref.path);
      if (files.empty()) {
        return Status::bad_input(where + " '" + printable_text(ref.path) +
                                 "': no file for any UDIM tile (1001 to 1999) was found");
      }
    } else {
      files.emplace_back(0, ref.path);
    }
    index = static_cast<int>(out.textures.size());
    out.textures.emplace_back();
    out.textures.back().path = ref.path;
    out.textures.back().color = color;
    for (auto& [tile, path] : files)
      reads.push_back(Read{static_cast<std::size_t>(index), tile, path, where, nullptr});
    return Status::ok();
  };
  for (std::size_t i = 0; i < high.material_defs.size(); ++i) {
    const Material& m = high.material_defs[i];
    MaterialTextures& t = out.by_material[i];
    if (needs.base_color) NMBAKE_TRY(plan(m, "base colour", m.base_color_texture, true, t.base_color));
    if (needs.roughness) NMBAKE_TRY(plan(m, "roughness", m.roughness_texture, false, t.roughness));
    if (needs.metallic) NMBAKE_TRY(plan(m, "metallic", m.metallic_texture, false, t.metallic));
    if (needs.emissive) NMBAKE_TRY(plan(m, "emission", m.emissive_texture, true, t.emissive));
    if (needs.opacity) NMBAKE_TRY(plan(m, "opacity", m.opacity_texture, false, t.opacity));
    // A normal texture is data (linear), +Y up.
    if (needs.normal) NMBAKE_TRY(plan(m, "normal", m.normal_texture, false, t.normal));
  }
  // The reads side by side (a PNG decodes on one core); the first failure
  // in material order is the one reported.
  std::vector<Status> status(reads.size());
  std::vector<MipTexture> mips(reads.size());
  tbb::parallel_for(std::size_t{0}, reads.size(), [&](std::size_t r) {
    Image image;
    const Read& read = reads[r];
    if (Status s = read_texture_image(read.path, read.embedded, out.textures[read.texture].color, image);
        !s.is_ok()) {
      status[r] = Status::bad_input(
          read.where +
          (read.embedded != nullptr ? " (" + read.path + "): " : " '" + printable_text(read.path) + "': ") +
          s.message());
      return;
    }
    mips[r] = make_mip_texture(std::move(image));
  });
  for (std::size_t r = 0; r < reads.size(); ++r) {
    NMBAKE_TRY(status[r]);
    if (reads[r].embedded == nullptr) out.files.push_back(reads[r].path);
    for (const MipLevel& level : mips[r].levels) out.bytes += level.data.size() * sizeof(float);
    out.textures[reads[r].texture].tiles.emplace(reads[r].tile, std::move(mips[r]));
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  return Status::ok();
}

}  // namespace nmbake
