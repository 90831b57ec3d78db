// Integer-hash lattice noise: Perlin, "Improving Noise" (SIGGRAPH 2002) for the
// fade curve and the gradient set; fBm after Musgrave ("Texturing and
// Modeling", ch. 16). See noise.hpp.
#include "noise.hpp"

#include <algorithm>
#include <cmath>

namespace nmbake::noise {

std::uint32_t mix32(std::uint32_t x) {
  x ^= x >> 16;
  x *= 0x85ebca6bu;
  x ^= x >> 13;
  x *= 0xc2b2ae35u;
  x ^= x >> 16;
  return x;
}

std::uint32_t hash(std::uint32_t seed, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  // Each input is folded in with a different odd multiplier, then mixed, so
  // (a, b) and (b, a) give unrelated values.
  std::uint32_t h = mix32(seed * 0x9e3779b1u + 0x7f4a7c15u);
  h = mix32(h ^ (a * 0x85ebca77u));
  h = mix32(h ^ (b * 0xc2b2ae3du));
  h = mix32(h ^ (c * 0x27d4eb2fu));
  return h;
}

double unit_from_hash(std::uint32_t h) { return static_cast<double>(h >> 8) * (1.0 / 16777216.0); }

namespace {

double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

double lerp(double a, double b, double t) { return a + (b - a) * t; }

// Dot product of the offset with one of the 12 cube-edge gradients.
double gradient_dot(std::uint32_t h, double x, double y, double z) {
  switch (h % 12u) {
    case 0:
      return x + y;
    case 1:
      return -x + y;
    case 2:
      return x - y;
    case 3:
      return -x - y;
    case 4:
      return x + z;
    case 5:
      return -x + z;
    case 6:
      return x - z;
    case 7:
      return -x - z;
    case 8:
      return y + z;
    case 9:
      return -y + z;
    case 10:
      return y - z;
    default:
      return -y - z;
  }
}

struct Cell {
  std::uint32_t x, y, z;  // lattice corner (wrapping two's complement is fine for hashing)
  double fx, fy, fz;      // position inside the cell, [0, 1)
};

Cell cell_of(const glm::dvec3& p) {
  const double x0 = std::floor(p.x);
  const double y0 = std::floor(p.y);
  const double z0 = std::floor(p.z);
  return {static_cast<std::uint32_t>(static_cast<std::int64_t>(x0)),
          static_cast<std::uint32_t>(static_cast<std::int64_t>(y0)),
          static_cast<std::uint32_t>(static_cast<std::int64_t>(z0)),
          p.x - x0,
          p.y - y0,
          p.z - z0};
}

// Hashes of the 8 corners of a cell, x first, then y, then z: 14 mixes
// instead of 8 full hashes, and still a different value for every corner.
void corner_hashes(std::uint32_t seed, const Cell& c, std::uint32_t (&out)[8]) {
  const std::uint32_t base = mix32(seed * 0x9e3779b1u + 0x7f4a7c15u);
  std::uint32_t hx[2], hxy[4];
  for (std::uint32_t dx = 0; dx < 2; ++dx) hx[dx] = mix32(base ^ ((c.x + dx) * 0x85ebca77u));
  for (std::uint32_t k = 0; k < 4; ++k) hxy[k] = mix32(hx[k & 1] ^ ((c.y + (k >> 1)) * 0xc2b2ae3du));
  for (std::uint32_t k = 0; k < 8; ++k) out[k] = mix32(hxy[k & 3] ^ ((c.z + (k >> 2)) * 0x27d4eb2fu));
}

double trilinear(const double (&corner)[8], const Cell& c) {
  const double u = fade(c.fx), v = fade(c.fy), w = fade(c.fz);
  const double x00 = lerp(corner[0], corner[1], u);
  const double x10 = lerp(corner[2], corner[3], u);
  const double x01 = lerp(corner[4], corner[5], u);
  const double x11 = lerp(corner[6], corner[7], u);
  return lerp(lerp(x00, x10, v), lerp(x01, x11, v), w);
}

}  // namespace

double gradient_noise(std::uint32_t seed, const glm::dvec3& p) {
  const Cell c = cell_of(p);
  std::uint32_t h[8];
  corner_hashes(seed, c, h);
  double corner[8];
  for (int k = 0; k < 8; ++k) {
    const double dx = k & 1, dy = (k >> 1) & 1, dz = (k >> 2) & 1;
    corner[k] = gradient_dot(h[k], c.fx - dx, c.fy - dy, c.fz - dz);
  }
  return std::clamp(trilinear(corner, c), -1.0, 1.0);
}

double value_noise(std::uint32_t seed, const glm::dvec3& p) {
  const Cell c = cell_of(p);
  std::uint32_t h[8];
  corner_hashes(seed, c, h);
  double corner[8];
  for (int k = 0; k < 8; ++k) corner[k] = 2.0 * unit_from_hash(h[k]) - 1.0;
  return trilinear(corner, c);
}

double fbm(std::uint32_t seed, const glm::dvec3& p, const FbmParams& params) {
  double sum = 0.0;
  double amplitude_sum = 0.0;
  double amplitude = 1.0;
  double frequency = 1.0;
  for (int octave = 0; octave < params.octave_count; ++octave) {
    sum += amplitude *
           gradient_noise(hash(seed, static_cast<std::uint32_t>(octave), 0x6f637476u), p * frequency);
    amplitude_sum += amplitude;
    amplitude *= params.gain;
    frequency *= params.lacunarity;
  }
  // octave_count <= 0 has a defined result: no detail.
  return amplitude_sum > 0.0 ? sum / amplitude_sum : 0.0;
}

}  // namespace nmbake::noise
