// libFuzzer target: gzip-compressed files (core/io/gzip.h) on arbitrary bytes, inflated and
// parsed as PCD and as text, the two formats most often shipped gzipped. Seeds start with the
// gzip magic, so mutations exercise the inflater rather than the readers' own rejections.

#include "fuzz/reader_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kPcd, data, size);
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kXyz, data, size);
  return 0;
}
