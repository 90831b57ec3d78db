// Private to the load stage: tinygltf (Debian's libtinygltf-dev, header-only
// 2.7) with the one configuration every file of ours includes it with.
//
// nmbake reads and writes geometry only, so image decoding and encoding are
// compiled out (no stb headers needed) and external images are never read;
// tinygltf_impl.cpp compiles the implementation once. JSON is nlohmann's,
// which the project already uses.
#pragma once

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>
