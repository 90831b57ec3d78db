// The one translation unit that compiles tinygltf's implementation (see
// tinygltf.hpp for the configuration). Debian also ships it as
// libtinygltf.so, but that build decodes images through libstb, which a
// geometry loader has no use for.
#define TINYGLTF_IMPLEMENTATION
#include "load/tinygltf.hpp"
