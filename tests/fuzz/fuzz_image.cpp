// Images through read_image(), as height2normal, preview --map and diff read
// them (the OpenImageIO module, our header and budget checks). The first
// byte picks the extension (a Targa, which has no signature, is read by its
// name); the rest is the file.
#include "fuzz_util.hpp"
#include "nmbake/image.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const char* const kNames[] = {"input.png", "input.exr", "input.tif", "input.tga"};
  const nmbake::fuzz::InputFile file(data + 1, size - 1, kNames[data[0] % 4]);
  nmbake::Image image;
  (void)nmbake::read_image(file.path(), image);
  return 0;
}
