// libFuzzer target: the legacy VTK reader (core/io/vtk_reader.h) on arbitrary bytes.

#include "fuzz/reader_fuzzer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  shapeid::fuzz::FuzzReader(shapeid::CloudFormat::kVtk, data, size);
  return 0;
}
