// libFuzzer target: the PCD reader (core/io/pcd_reader.h) on arbitrary bytes.

#include "fuzz/reader_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kPcd, data, size);
  return 0;
}
