// libFuzzer target: the NumPy readers (core/io/npy_reader.h) on arbitrary bytes, as a .npy
// array and as a .npz archive.

#include "fuzz/reader_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kNpy, data, size);
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kNpz, data, size);
  return 0;
}
