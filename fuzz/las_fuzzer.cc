// libFuzzer target: the LAS reader (core/io/las_reader.h) on arbitrary bytes.

#include "fuzz/reader_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kLas, data, size);
  return 0;
}
