// libFuzzer target: the STL reader (core/io/stl_reader.h), ascii and binary on arbitrary bytes.

#include "fuzz/reader_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kStl, data, size);
  return 0;
}
