// Deterministic integer-hash noise for the scene generators.
//
// Lattice noise as in Perlin, "Improving Noise" (SIGGRAPH 2002): quintic fade
// 6t^5 - 15t^4 + 10t^3 and gradients from the 12 cube-edge directions, but the
// lattice hash is an integer hash of (seed, x, y, z) instead of a permutation
// table, so any seed gives an independent field and nothing is random per run.
// Fractal Brownian motion (fBm) is the usual octave sum (Musgrave, "Texturing
// and Modeling", ch. 16).
//
// Everything is computed in double and depends only on the arguments: the same
// call gives the same bits on every thread.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>

namespace nmbake::noise {

// Avalanching 32-bit mix (the MurmurHash3 fmix32 finalizer constants).
std::uint32_t mix32(std::uint32_t x);

// Hash of a seed and up to three integers; order-sensitive.
std::uint32_t hash(std::uint32_t seed, std::uint32_t a, std::uint32_t b = 0, std::uint32_t c = 0);

// Uniform in [0, 1) from the 24 high bits of a hash (exact in float and double).
double unit_from_hash(std::uint32_t h);

// Gradient noise in about [-1, 1] (clamped to it), 0 on every lattice point.
double gradient_noise(std::uint32_t seed, const glm::dvec3& p);

// Value noise in [-1, 1]: hashed lattice values, quintic interpolation.
double value_noise(std::uint32_t seed, const glm::dvec3& p);

struct FbmParams {
  int octave_count = 5;
  double lacunarity = 2.0;  // frequency ratio between octaves
  double gain = 0.5;        // amplitude ratio between octaves
};

// Sum of gradient-noise octaves divided by the sum of their amplitudes, so the
// result stays in [-1, 1]. Each octave has its own seed (no lattice alignment
// between octaves).
double fbm(std::uint32_t seed, const glm::dvec3& p, const FbmParams& params = {});

}  // namespace nmbake::noise
