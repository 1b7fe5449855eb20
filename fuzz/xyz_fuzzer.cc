// libFuzzer target: the text reader (core/io/xyz_reader.h) on arbitrary bytes, in both of its
// dialects (.xyz / .txt: blank- or comma-separated; .csv: comma- or semicolon-separated).

#include "fuzz/reader_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kXyz, data, size);
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kCsv, data, size);
  return 0;
}
