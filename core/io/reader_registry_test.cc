#include "core/io/reader_registry.h"

#include <cstdint>
#include <cstring>
#include <set>
#include <string>

#include "absl/strings/ascii.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

TEST(ReaderRegistryTest, OneEntryPerFormatInEnumOrderWithDistinctNamesAndExtensions) {
  const std::vector<CloudReaderKind>& readers = RegisteredReaders();
  ASSERT_EQ(readers.size(), static_cast<size_t>(CloudFormat::kCsv) + 1);
  std::set<std::string> names, extensions;
  for (size_t i = 0; i < readers.size(); ++i) {
    const CloudReaderKind& reader = readers[i];
    EXPECT_EQ(reader.format, static_cast<CloudFormat>(i)) << reader.name;
    EXPECT_EQ(&ReaderFor(reader.format), &reader);
    EXPECT_TRUE(names.insert(reader.name).second) << reader.name;
    ASSERT_FALSE(reader.extensions.empty()) << reader.name;
    EXPECT_EQ(reader.extensions[0], "." + reader.name);
    for (const std::string& extension : reader.extensions) {
      EXPECT_EQ(extension, absl::AsciiStrToLower(extension));
      EXPECT_EQ(extension[0], '.');
      EXPECT_TRUE(extensions.insert(extension).second) << extension;
    }
    EXPECT_NE(reader.parse, nullptr) << reader.name;
  }
}

std::string BinaryStl(uint32_t triangles, const std::string& header_start) {
  std::string stl(80, ' ');
  stl.replace(0, header_start.size(), header_start);
  char count[4];
  std::memcpy(count, &triangles, 4);
  stl.append(count, 4);
  stl.append(size_t{50} * triangles, '\0');
  return stl;
}

// Each format's first bytes, as the tools that write it begin them; each carries exactly one
// signature, so the order of the table cannot matter.
TEST(ReaderRegistryTest, EachSignatureIsItsFormatsAlone) {
  const std::vector<std::pair<std::string, CloudFormat>> starts = {
      {"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n", CloudFormat::kPcd},
      {"VERSION .7\nFIELDS x y z\n", CloudFormat::kPcd},
      {"ply\nformat binary_little_endian 1.0\n", CloudFormat::kPly},
      {"ply\r\nformat ascii 1.0\r\n", CloudFormat::kPly},
      {"OFF\n8 6 0\n", CloudFormat::kOff},
      {"OFF490 518 0\n", CloudFormat::kOff},
      {"solid cube\n  facet normal 0 0 1\n", CloudFormat::kStl},
      {BinaryStl(2, "binary"), CloudFormat::kStl},
      {BinaryStl(1, "solid exported by a tool that writes binary"), CloudFormat::kStl},
      {"# vtk DataFile Version 3.0\n", CloudFormat::kVtk},
      {std::string("LASF\0\0\0\0", 8), CloudFormat::kLas},
      {std::string("\x93NUMPY\x01\x00", 8), CloudFormat::kNpy},
      {std::string("PK\x03\x04\x14\x00", 6), CloudFormat::kNpz},
  };
  for (const auto& [contents, format] : starts) {
    int matches = 0;
    for (const CloudReaderKind& reader : RegisteredReaders()) {
      if (reader.has_signature != nullptr && reader.has_signature(contents)) ++matches;
    }
    EXPECT_EQ(matches, 1) << contents.substr(0, 16);
    EXPECT_EQ(CloudFormatBySignature(contents), format) << contents.substr(0, 16);
  }
}

TEST(ReaderRegistryTest, TextAndUnknownContentsHaveNoSignature) {
  for (const std::string contents : {"", "1 2 3\n4 5 6\n", "x,y,z\n1,2,3\n", "v 1 2 3\nf 1 2 3\n",
                                     "solidity 1 2 3\n", "plywood", "ASTM-E57"}) {
    EXPECT_EQ(CloudFormatBySignature(contents), std::nullopt) << contents;
  }
  EXPECT_EQ(FormatsWithSignatures(), "pcd, ply, off, stl, vtk, las, npy, npz");
}

}  // namespace
}  // namespace shapeid
