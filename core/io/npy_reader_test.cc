#include "core/io/npy_reader.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/io/io_testing.h"
#include "core/io/point_cloud_reader.h"
#include "core/io/zip_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::absl::StatusCode;
using ::testing::HasSubstr;

// A .npy file as numpy writes it: magic, version, header length, the dict padded with spaces
// and a '\n' so that the data starts at a multiple of 64, then `data`.
std::string Npy(absl::string_view dict, absl::string_view data, int major = 1) {
  const size_t prefix = major == 1 ? 10 : 12;
  std::string header(dict);
  header.append((64 - (prefix + header.size() + 1) % 64) % 64, ' ');
  header.push_back('\n');
  std::string file("\x93NUMPY", 6);
  file.push_back(static_cast<char>(major));
  file.push_back('\0');
  if (major == 1) {
    AppendBytes(&file, static_cast<uint16_t>(header.size()));
  } else {
    AppendBytes(&file, static_cast<uint32_t>(header.size()));
  }
  return file + header + std::string(data);
}

std::string Dict(absl::string_view descr, absl::string_view shape, bool fortran = false) {
  return absl::StrCat("{'descr': ", descr, ", 'fortran_order': ", fortran ? "True" : "False",
                      ", 'shape': ", shape, ", }");
}

// Values in host (little-endian) byte order.
template <typename T>
std::string Values(std::initializer_list<T> values) {
  std::string out;
  for (T v : values) AppendBytes(&out, v);
  return out;
}

// Values in big-endian byte order.
template <typename T>
std::string BigEndian(std::initializer_list<T> values) {
  std::string out;
  for (T v : values) {
    std::string bytes;
    AppendBytes(&bytes, v);
    out.append(bytes.rbegin(), bytes.rend());
  }
  return out;
}

template <typename T>
void Put(std::string* s, size_t at, T value) {
  std::memcpy(&(*s)[at], &value, sizeof value);
}

void ExpectPoint(const PointCloud& cloud, size_t i, float x, float y, float z) {
  ASSERT_LT(i, cloud.size());
  EXPECT_EQ(cloud.point(i).x(), x) << "point " << i;
  EXPECT_EQ(cloud.point(i).y(), y) << "point " << i;
  EXPECT_EQ(cloud.point(i).z(), z) << "point " << i;
}

// Points (0 1 2), (10 11 12), (20 21 22), ...
void ExpectRamp(const absl::StatusOr<ReadResult>& r, size_t n) {
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), n);
  for (size_t i = 0; i < n; ++i) {
    const float b = 10.0f * static_cast<float>(i);
    ExpectPoint(r->cloud, i, b, b + 1, b + 2);
  }
}

TEST(NpyReaderTest, Float32RowsWithExtraColumns) {
  const std::string file =
      Npy(Dict("'<f4'", "(2, 4)"), Values<float>({0.5f, -1.25f, 3e6f, 7, 1e-3f, 2, -3, 9}));
  EXPECT_EQ(file.size(), 128u + 32u);  // numpy aligns the data to 64 bytes
  const absl::StatusOr<ReadResult> r = ParseNpy(file, "a.npy", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 2u);
  ExpectPoint(r->cloud, 0, 0.5f, -1.25f, 3e6f);
  ExpectPoint(r->cloud, 1, 1e-3f, 2, -3);
}

TEST(NpyReaderTest, Version2BigEndianFloat64) {
  const std::string file =
      Npy(Dict("'>f8'", "(2, 3)"), BigEndian<double>({0.1, 0.2, 0.3, 1e10, -1e-10, 3}), 2);
  const absl::StatusOr<ReadResult> r = ParseNpy(file, "b.npy", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 2u);
  ExpectPoint(r->cloud, 0, 0.1f, 0.2f, 0.3f);
  ExpectPoint(r->cloud, 1, 1e10f, -1e-10f, 3.0f);
}

TEST(NpyReaderTest, Version3Utf8FieldNames) {
  const std::string file =
      Npy("{'descr': [('temp\xc3\xa9rature', '<f4'), ('x', '<f4'), ('y', '<f4'), ('z', '<f4')], "
          "'fortran_order': False, 'shape': (1,), }",
          Values<float>({99, 1, 2, 3}), 3);
  const absl::StatusOr<ReadResult> r = ParseNpy(file, "c.npy", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 1u);
  ExpectPoint(r->cloud, 0, 1, 2, 3);
}

TEST(NpyReaderTest, IntegerAndHalfDtypes) {
  struct Case {
    const char* descr;
    std::string data;
  };
  const Case cases[] = {
      {"'|i1'", Values<int8_t>({0, 1, 2, 10, 11, 12, -128, 127, -1})},
      {"'|u1'", Values<uint8_t>({0, 1, 2, 10, 11, 12, 255, 128, 7})},
      {"'<i2'", Values<int16_t>({0, 1, 2, 10, 11, 12, -32768, 32767, -1})},
      {"'>i2'", BigEndian<int16_t>({0, 1, 2, 10, 11, 12, -32768, 32767, -1})},
      {"'<u2'", Values<uint16_t>({0, 1, 2, 10, 11, 12, 65535, 256, 7})},
      {"'<i4'", Values<int32_t>({0, 1, 2, 10, 11, 12, -2147483647 - 1, 2147483647, -1})},
      {"'>u4'", BigEndian<uint32_t>({0, 1, 2, 10, 11, 12, 4294967295u, 65536, 7})},
      {"'<i8'", Values<int64_t>({0, 1, 2, 10, 11, 12, -(int64_t{1} << 40), int64_t{1} << 53, -1})},
      {"'<u8'", Values<uint64_t>({0, 1, 2, 10, 11, 12, uint64_t{1} << 63, 1, 7})},
      // float16: 0, 1, 2, 10, 11, 12, 65504 (largest), 2^-24 (smallest subnormal), -2.5
      {"'<f2'", Values<uint16_t>({0, 0x3c00, 0x4000, 0x4900, 0x4980, 0x4a00, 0x7bff, 1, 0xc100})},
  };
  const float third[][3] = {{-128, 127, -1},
                            {255, 128, 7},
                            {-32768, 32767, -1},
                            {-32768, 32767, -1},
                            {65535, 256, 7},
                            {-2147483648.0f, 2147483647.0f, -1},
                            {4294967295.0f, 65536, 7},
                            {-1099511627776.0f, 9007199254740992.0f, -1},
                            {9223372036854775808.0f, 1, 7},
                            {65504, 5.9604644775390625e-8f, -2.5f}};
  for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
    SCOPED_TRACE(cases[c].descr);
    const absl::StatusOr<ReadResult> r =
        ParseNpy(Npy(Dict(cases[c].descr, "(3, 3)"), cases[c].data), "i.npy", Raw());
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_EQ(r->cloud.size(), 3u);
    ExpectPoint(r->cloud, 0, 0, 1, 2);
    ExpectPoint(r->cloud, 1, 10, 11, 12);
    ExpectPoint(r->cloud, 2, third[c][0], third[c][1], third[c][2]);
  }
}

TEST(NpyReaderTest, NativeByteOrderAndNoByteOrder) {
  for (const char* descr : {"'=f4'", "'f4'"}) {
    ExpectRamp(ParseNpy(Npy(Dict(descr, "(1, 3)"), Values<float>({0, 1, 2})), "n.npy", Raw()), 1);
  }
}

TEST(NpyReaderTest, FortranOrder) {
  // Column-major (3, 3): all x, then all y, then all z.
  ExpectRamp(ParseNpy(Npy(Dict("'<f8'", "(3, 3)", true),
                          Values<double>({0, 10, 20, 1, 11, 21, 2, 12, 22})),
                      "f.npy", Raw()),
             3);
  // Column-major (2, 3, 4) organized cloud: element (h, w, c) at h + 2 w + 6 c; the fourth
  // column is skipped. Points come in C order: (0,0) (0,1) (0,2) (1,0) ...
  std::vector<float> data(24, -1.0f);
  for (int h = 0; h < 2; ++h) {
    for (int w = 0; w < 3; ++w) {
      for (int c = 0; c < 3; ++c) data[h + 2 * w + 6 * c] = 10.0f * (3 * h + w) + c;
    }
  }
  std::string bytes(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(float));
  ExpectRamp(ParseNpy(Npy(Dict("'<f4'", "(2, 3, 4)", true), bytes), "g.npy", Raw()), 6);
}

TEST(NpyReaderTest, OrganisedCloudIsReadAsRows) {
  std::string bytes;
  for (int p = 0; p < 6; ++p) {
    for (float v : {10.0f * p, 10.0f * p + 1, 10.0f * p + 2}) AppendBytes(&bytes, v);
  }
  ExpectRamp(ParseNpy(Npy(Dict("'<f4'", "(2, 3, 3)"), bytes), "o.npy", Raw()), 6);
}

TEST(NpyReaderTest, StructuredFieldsOfEveryKindAreSkipped) {
  // z f8 | rgb u1 | y >i2 | x >f4 | 3 pad bytes | normal f4 x 3 | nested (a i4, b S2) | title
  const std::string descr =
      "[('z', '<f8'), ('rgb', '|u1'), ('y', '>i2'), ('x', '>f4'), ('', '|V3'), "
      "('normal', '<f4', (3,)), ('nested', [('a', '<i4'), ('b', '|S2')]), "
      "(('time of day', 't'), '<M8[us]'), ('label', '<U2')]";
  const size_t itemsize = 8 + 1 + 2 + 4 + 3 + 12 + 6 + 8 + 8;
  std::string data;
  for (int i = 0; i < 2; ++i) {
    std::string record;
    AppendBytes<double>(&record, 10.0 * i + 2);
    record.push_back('\x7f');
    record += BigEndian<int16_t>({static_cast<int16_t>(10 * i + 1)});
    record += BigEndian<float>({10.0f * i});
    record.append(itemsize - record.size(), '\xee');
    data += record;
  }
  ExpectRamp(ParseNpy(Npy(Dict(descr, "(2,)"), data), "s.npy", Raw()), 2);
}

TEST(NpyReaderTest, StructuredOrganisedCloudAndFortranOrder) {
  // A (2, 2) record grid, as ros_numpy gives a PointCloud2: x y z intensity.
  const std::string descr = "[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('intensity', '<f4')]";
  std::string c_order, f_order;
  for (int p = 0; p < 4; ++p) {
    c_order += Values<float>({10.0f * p, 10.0f * p + 1, 10.0f * p + 2, 5});
  }
  for (int p : {0, 2, 1, 3}) {
    f_order += Values<float>({10.0f * p, 10.0f * p + 1, 10.0f * p + 2, 5});
  }
  ExpectRamp(ParseNpy(Npy(Dict(descr, "(2, 2)"), c_order), "r.npy", Raw()), 4);
  ExpectRamp(ParseNpy(Npy(Dict(descr, "(2, 2)", true), f_order), "r.npy", Raw()), 4);
}

TEST(NpyReaderTest, HeaderDictSyntaxVariants) {
  const std::string data = Values<float>({0, 1, 2});
  for (const char* dict : {
           "{'descr': '<f4', 'fortran_order': False, 'shape': (1, 3), }",
           "{\"shape\": (1,3), \"descr\": \"<f4\", \"fortran_order\": False}",
           "{ 'fortran_order' :False ,\t'shape':( 1 , 3 , ) ,'descr':u'<f4' }",
           "{'descr': '<f4', 'fortran_order': False, 'shape': (1L, 3L), }",  // Python 2
           "{'descr': r'<f4', 'fortran_order': False, 'shape': ((1), 3)}",
           "{'descr': '\\x3cf4', 'fortran_order': False, 'shape': (1, 3)}",
       }) {
    SCOPED_TRACE(dict);
    ExpectRamp(ParseNpy(Npy(dict, data), "h.npy", Raw()), 1);
  }
}

TEST(NpyReaderTest, NoElementsIsAnEmptyCloud) {
  for (const std::string& file :
       {Npy(Dict("'<f4'", "(0, 3)"), ""), Npy(Dict("'<f8'", "(4, 0, 3)"), ""),
        Npy(Dict("[('x', '<f4'), ('y', '<f4'), ('z', '<f4')]", "(0,)"), "")}) {
    const absl::StatusOr<ReadResult> r = ParseNpy(file, "e.npy");
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_TRUE(r->cloud.empty());
  }
}

TEST(NpyReaderTest, NonFinitePointsFollowTheOptions) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  const std::string file = Npy(Dict("'<f4'", "(2, 3)"), Values<float>({1, 2, 3, kNaN, 0, 0}));
  absl::StatusOr<ReadResult> r = ParseNpy(file, "nan.npy", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), 2u);
  ReadOptions drop = Raw();
  drop.drop_non_finite = true;
  r = ParseNpy(file, "nan.npy", drop);
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 1u);
  EXPECT_EQ(r->dropped_non_finite, 1u);
  // Too large for a float: the accumulator names the value's byte offset.
  ExpectError(
      ParseNpy(Npy(Dict("'<f8'", "(1, 3)"), Values<double>({0, 1e300, 0})), "big.npy", Raw()),
      StatusCode::kInvalidArgument, "big.npy", "byte offset 128: y = 1e+300");
}

TEST(NpyReaderTest, BadMagicVersionAndHeaderLength) {
  const std::string good = Npy(Dict("'<f4'", "(1, 3)"), Values<float>({0, 1, 2}));
  ExpectError(ParseNpy("P3\n1 1\n", "m.npy"), StatusCode::kInvalidArgument, "m.npy",
              "byte offset 0: a .npy file starts with \"\\x93NUMPY\"");
  ExpectError(ParseNpy(good.substr(0, 7), "m.npy"), StatusCode::kInvalidArgument, "m.npy",
              "byte offset 0");
  std::string v = good;
  v[6] = 4;
  ExpectError(ParseNpy(v, "v.npy"), StatusCode::kUnimplemented, "v.npy",
              "byte offset 6: .npy format version 4.0 is not read (1.0, 2.0 and 3.0 are)");
  v[6] = 1;
  v[7] = 1;
  ExpectError(ParseNpy(v, "v.npy"), StatusCode::kUnimplemented, "v.npy", "version 1.1");
  ExpectError(ParseNpy(good.substr(0, 9), "l.npy"), StatusCode::kInvalidArgument, "l.npy",
              "byte offset 8: the file ends inside the header length");
  ExpectError(ParseNpy(good.substr(0, 100), "l.npy"), StatusCode::kInvalidArgument, "l.npy",
              "byte offset 8: the header length 118 runs past the end of the file (90 bytes");
  std::string huge = Npy("", "", 2);
  Put<uint32_t>(&huge, 8, 2000000);
  huge.append(2000000, ' ');
  ExpectError(ParseNpy(huge, "l.npy"), StatusCode::kInvalidArgument, "l.npy",
              "byte offset 8: the header length 2000000 is over 1048576 bytes");
}

TEST(NpyReaderTest, MalformedHeaderDicts) {
  struct Case {
    std::string dict;
    const char* where;  // the byte offset (the header starts at 10) and the complaint
  };
  const Case cases[] = {
      {"",
       "byte offset 64: array header \"                                        ...\": "
       "expected a value, found the end of the header"},
      {"[1, 2]", "byte offset 10: array header \"[1, 2]"},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1, 3)} x",
       "byte offset 68: array header \"{'descr': '<f4', 'fortran_order': False,...\": expected "
       "the end of the header, found \"x\""},
      {"{'descr': '<f4, 'fortran_order': False, 'shape': (1, 3)}",
       "byte offset 27: array header \"{'descr': '<f4, 'fortran_order': False, ...\": expected "
       "',' or '}', found \"f\""},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1, 3)",
       "expected ',' or '}', found the end of the header"},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1; 3)}", "expected ',' or ')'"},
      {"{'descr': '<f4', 'fortran_order': false, 'shape': (1, 3)}", "unknown name \"false\""},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1, 3.0)}", "expected ',' or ')'"},
      {"{'descr': '<f4\\x4', 'fortran_order': False, 'shape': (1, 3)}", "hexadecimal digit"},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1, 3), 'extra': 1}",
       "byte offset 68: array header \"{'descr': '<f4', 'fortran_order': False,...\": "
       "unexpected key \"extra\"; a .npy header has exactly 'descr', 'fortran_order' and "
       "'shape'"},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1, 3), 'shape': (1, 3)}",
       "key \"shape\" appears twice"},
      {"{'descr': '<f4', 'fortran_order': False}", "the header has no 'shape' key"},
      {"{'descr': '<f4', 'fortran_order': 0, 'shape': (1, 3)}",
       "'fortran_order' is not True or False"},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': [1, 3]}", "'shape' is not a tuple"},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1, -3)}",
       "byte offset 64: array header \"{'descr': '<f4', 'fortran_order': False,...\": 'shape' "
       "holds something other than non-negative integers"},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999, 3)}",
       "non-negative integers"},
      {"{'descr': 3, 'fortran_order': False, 'shape': (1, 3)}",
       "'descr' is neither a type string nor a list of fields"},
      {std::string(40, '(') + std::string(40, ')'), "values nest deeper than 32 levels"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.dict);
    ExpectError(ParseNpy(Npy(c.dict, Values<float>({0, 1, 2})), "d.npy"),
                StatusCode::kInvalidArgument, "d.npy", c.where);
  }
}

TEST(NpyReaderTest, DtypeErrors) {
  struct Case {
    const char* descr;
    StatusCode code;
    const char* where;
  };
  const Case cases[] = {
      {"'|f4'", StatusCode::kInvalidArgument,
       "byte offset 20: dtype '|f4' has no byte order ('|') but more than one byte per value; "
       "expected a NumPy type string such as '<f4'"},
      {"'<i3'", StatusCode::kInvalidArgument, "dtype '<i3' is not a valid type"},
      {"'<q8'", StatusCode::kInvalidArgument, "dtype '<q8' has an unknown kind"},
      {"'<f'", StatusCode::kInvalidArgument, "dtype '<f' has no size"},
      {"'<f99999999999999'", StatusCode::kInvalidArgument, "has an absurd size"},
      {"'|O'", StatusCode::kInvalidArgument, "byte offset 20: pickled object arrays are not read"},
      {"[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('o', '|O')]", StatusCode::kInvalidArgument,
       "pickled object arrays are not read"},
      {"'<c8'", StatusCode::kUnimplemented,
       "byte offset 20: coordinates of dtype '<c8' are not read (float f2, f4, f8 and integer "
       "i1..i8, u1..u8 are)"},
      {"'|b1'", StatusCode::kUnimplemented, "coordinates of dtype '|b1' are not read"},
      {"'<f16'", StatusCode::kUnimplemented, "coordinates of dtype '<f16' are not read"},
      {"'|S4'", StatusCode::kUnimplemented, "coordinates of dtype '|S4' are not read"},
      {"[('x', '<f4'), ('y', '<f4'), ('intensity', '<f4'), ('', '|V4')]",
       StatusCode::kInvalidArgument,
       "byte offset 20: the structured dtype has no 'z' field (its fields: 'x', 'y', "
       "'intensity', ''); fields named x, y and z are read"},
      {"[('X', '<f4'), ('Y', '<f4'), ('Z', '<f4')]", StatusCode::kInvalidArgument,
       "has no 'x' field"},
      {"[]", StatusCode::kInvalidArgument, "has no 'x' field (its fields: none)"},
      {"[('x', '<f4'), ('y', '<f4'), ('z', '<f4', (3,))]", StatusCode::kUnimplemented,
       "field 'z' is a sub-array; only scalar x, y and z fields are read"},
      {"[('x', [('a', '<f4')]), ('y', '<f4'), ('z', '<f4')]", StatusCode::kUnimplemented,
       "field 'x' is a nested record"},
      {"[('x', '<f4'), ('y', '<c8'), ('z', '<f4')]", StatusCode::kUnimplemented,
       "coordinates of dtype '<c8' are not read"},
      {"[('x', '<f4'), ('y', '<f4'), ('x', '<f4'), ('z', '<f4')]", StatusCode::kInvalidArgument,
       "field 'x' appears twice"},
      {"[('x', '<f4'), ('y', '<f4'), 'z']", StatusCode::kInvalidArgument,
       "a structured dtype's field is (name, type) or (name, type, shape)"},
      {"[(3, '<f4'), ('y', '<f4'), ('z', '<f4')]", StatusCode::kInvalidArgument,
       "a field's name is not a string"},
      {"[('x', 4), ('y', '<f4'), ('z', '<f4')]", StatusCode::kInvalidArgument,
       "a field's type is not a type string or a list of fields"},
      {"[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('n', '<f4', (-1,))]",
       StatusCode::kInvalidArgument, "sub-array shape is not a non-negative integer"},
      {"[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('n', '|V1099511627776', (4194304,))]",
       StatusCode::kInvalidArgument, "item size is absurdly large"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.descr);
    const std::string shape = c.descr[0] == '[' ? "(1,)" : "(1, 3)";
    ExpectError(ParseNpy(Npy(Dict(c.descr, shape), Values<float>({0, 1, 2})), "t.npy"), c.code,
                "t.npy", c.where);
  }
}

TEST(NpyReaderTest, ShapesThatAreNotPointArrays) {
  struct Case {
    const char* descr;
    const char* shape;
    const char* where;
  };
  const Case cases[] = {
      {"'<f4'", "(3,)",
       "byte offset 60: shape (3,) is not a point array; expected (N, 3) or more columns (one "
       "point is (1, 3)), or (H, W, 3) for an organized cloud"},
      {"'<f4'", "()", "shape () is not a point array"},
      {"'<f4'", "(1, 1, 1, 3)", "shape (1, 1, 1, 3) is not a point array"},
      {"'<f4'", "(3, 2)", "byte offset 60: shape (3, 2) has 2 columns; x, y and z need 3"},
      {"[('x', '<f4'), ('y', '<f4'), ('z', '<f4')]", "(1, 1, 1)",
       "a structured array of shape (1, 1, 1) is not a point array; expected (N,) or (H, W)"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.shape);
    ExpectError(ParseNpy(Npy(Dict(c.descr, c.shape), Values<float>({0, 1, 2})), "p.npy"),
                StatusCode::kInvalidArgument, "p.npy", c.where);
  }
}

TEST(NpyReaderTest, DataSizeMustMatchTheShape) {
  const std::string data = Values<float>({0, 1, 2, 10, 11, 12});
  ExpectError(ParseNpy(Npy(Dict("'<f4'", "(2, 3)"), data.substr(0, 20)), "s.npy"),
              StatusCode::kInvalidArgument, "s.npy",
              "byte offset 128: the data is 20 bytes, but shape (2, 3) of '<f4' needs 24 bytes");
  ExpectError(ParseNpy(Npy(Dict("'<f4'", "(2, 3)"), data + "\n"), "s.npy"),
              StatusCode::kInvalidArgument, "s.npy",
              "byte offset 128: the data is 25 bytes, but shape (2, 3) of '<f4' needs 24 bytes");
  ExpectError(
      ParseNpy(Npy(Dict("[('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('i', '<u2')]", "(2,)"), data),
               "s.npy"),
      StatusCode::kInvalidArgument, "s.npy",
      "the data is 24 bytes, but shape (2,) of a structured dtype of 14 bytes needs 28 bytes");
  // A header announcing 10^12 points fails at once.
  ExpectError(ParseNpy(Npy(Dict("'<f8'", "(1000000000000, 3)"), data), "s.npy"),
              StatusCode::kInvalidArgument, "s.npy",
              "the data is 24 bytes, but shape (1000000000000, 3) of '<f8' needs 24000000000000 "
              "bytes");
  ExpectError(ParseNpy(Npy(Dict("'<f8'", "(4294967296, 4294967296, 3)"), data), "s.npy"),
              StatusCode::kInvalidArgument, "s.npy", "needs more than 2^62 bytes");
}

// ---- .npz ----

// Two points (0 1 2) (10 11 12), float32.
std::string RampNpy() { return Npy(Dict("'<f4'", "(2, 3)"), Values<float>({0, 1, 2, 10, 11, 12})); }

TEST(NpzReaderTest, MemberChoice) {
  const std::string other = Npy(Dict("'<f4'", "(1, 3)"), Values<float>({7, 7, 7}));
  // The known names, in priority order, whatever the archive order.
  ExpectRamp(ParseNpz(Zip({{"arr_1.npy", other},
                           {"arr_0.npy", other},
                           {"points.npy", RampNpy()},
                           {"xyz.npy", other}}),
                      "c.npz", Raw()),
             2);
  ExpectRamp(ParseNpz(Zip({{"normals.npy", other}, {"cloud.npy", other}, {"pcd.npy", RampNpy()}}),
                      "c.npz", Raw()),
             2);
  ExpectRamp(ParseNpz(Zip({{"labels.npy", other}, {"arr_0.npy", RampNpy(), 8}}), "c.npz", Raw()),
             2);
  // One member, whatever its name.
  ExpectRamp(ParseNpz(Zip({{"scan_17.npy", RampNpy(), 8}}), "c.npz", Raw()), 2);
  const std::string several = Zip({{"normals.npy", other}, {"labels.npy", other}});
  ExpectError(ParseNpz(several, "c.npz"), StatusCode::kInvalidArgument, "c.npz",
              absl::StrCat("byte offset ", DirectoryOffset(several),
                           ": the archive holds 2 arrays (\"normals.npy\", \"labels.npy\") and "
                           "none is named points.npy, xyz.npy, pcd.npy, cloud.npy or arr_0.npy, "
                           "the names looked for"));
}

TEST(NpzReaderTest, MemberErrorsNameTheArchiveAndTheMember) {
  const std::string zip = Zip({{"points.npy", RampNpy().substr(0, 150), 8}});
  ExpectError(ParseNpz(zip, "m.npz"), StatusCode::kInvalidArgument, "m.npz:points.npy",
              "m.npz:points.npy: byte offset 128: the data is 22 bytes");
}

TEST(NpzReaderTest, EachFormatIsReadUnderTheOthersName) {
  // As np.load: the magic bytes decide.
  ExpectRamp(ParseNpz(RampNpy(), "really.npz", Raw()), 2);
  ExpectRamp(ParseNpy(Zip({{"points.npy", RampNpy()}}), "really.npy", Raw()), 2);
}

TEST(NpzReaderTest, ReadPointCloudByExtension) {
  const std::string npz = WriteTempFile("p.npz", Zip({{"xyz.npy", RampNpy(), 8, true}}, true));
  ExpectRamp(ReadPointCloud(npz, Raw()), 2);
  const std::string npy = WriteTempFile("p.npy", RampNpy());
  ExpectRamp(ReadPointCloud(npy, Raw()), 2);
}

TEST(NpzReaderTest, NotAZipArchive) {
  ExpectError(ParseNpz("", "n.npz"), StatusCode::kInvalidArgument, "n.npz",
              "byte offset 0: not a zip archive: no end-of-central-directory record (PK\\5\\6) "
              "in its last 0 bytes; a .npz file is a zip of .npy arrays");
  ExpectError(ParseNpz(std::string(70000, 'x'), "n.npz"), StatusCode::kInvalidArgument, "n.npz",
              "byte offset 4443: not a zip archive: no end-of-central-directory record "
              "(PK\\5\\6) in its last 65557 bytes");
  ExpectError(ParseNpz(Zip({}), "n.npz"), StatusCode::kInvalidArgument, "n.npz",
              "byte offset 10: the archive is empty; a .npz file holds .npy arrays");
}

TEST(NpyReaderTest, RandomCorruptionsNameTheFile) {
  const std::string npy =
      Npy(Dict("[('x', '<f4'), ('y', '>f8'), ('z', '<i2'), ('i', '|u1')]", "(3,)"),
          std::string(3 * 15, '\x40'));
  const char replacements[] = "0123456789 ,()[]{}'\":<>|=fiuOVbcTFxyz\n\\\x93\x01\x02\x00\xff";
  uint64_t state = 1;
  ExpectCorruptionsNameTheFile(
      npy, "corrupt.npy", absl::string_view(replacements, sizeof replacements - 1), &state,
      [](const std::string& contents) { return ParseNpy(contents, "corrupt.npy"); });
  ExpectCorruptionsNameTheFile(
      RampNpy(), "corrupt.npy", absl::string_view(replacements, sizeof replacements - 1), &state,
      [](const std::string& contents) { return ParseNpy(contents, "corrupt.npy"); });
}

TEST(NpzReaderTest, RandomCorruptionsNameTheFile) {
  const char replacements[] = "\x00\x01\x02\x03\x04\x05\x06\x07\x08\xff\xfePK";
  uint64_t state = 7;
  for (const std::string& zip : {Zip({{"points.npy", RampNpy(), 8}, {"b.npy", RampNpy()}}),
                                 Zip({{"arr_0.npy", RampNpy(), 0, true}}, true)}) {
    ExpectPrefixesNameTheFile(zip, "prefix.npz", [](const std::string& contents) {
      return ParseNpz(contents, "prefix.npz");
    });
    ExpectCorruptionsNameTheFile(
        zip, "corrupt.npz", absl::string_view(replacements, sizeof replacements - 1), &state,
        [](const std::string& contents) { return ParseNpz(contents, "corrupt.npz"); });
  }
}

// The checked-in malformed files (tests/bad_input/testdata) fail for their one defect.
TEST(NpyReaderTest, BadInputFilesFailForTheirDefect) {
  struct Case {
    const char* file;
    StatusCode code;
    const char* where;
  };
  const Case cases[] = {
      {"npy_shape_huge.npy", StatusCode::kInvalidArgument,
       "byte offset 128: the data is 24 bytes, but shape (1000000000000, 3) of '<f4' needs "
       "12000000000000 bytes"},
      {"npy_data_truncated.npy", StatusCode::kInvalidArgument,
       "byte offset 128: the data is 20 bytes, but shape (2, 3) of '<f4' needs 24 bytes"},
      {"npy_object_dtype.npy", StatusCode::kInvalidArgument,
       "byte offset 20: pickled object arrays are not read"},
      {"npy_header_unclosed_dict.npy", StatusCode::kInvalidArgument,
       "expected a value, found the end of the header"},
      {"npy_structured_no_z.npy", StatusCode::kInvalidArgument,
       "byte offset 20: the structured dtype has no 'z' field"},
      {"npz_crc_mismatch.npz", StatusCode::kInvalidArgument,
       "member \"points.npy\": its data's CRC-32 is 0x"},
      {"npz_uncompressed_size_huge.npz", StatusCode::kInvalidArgument,
       "member \"points.npy\" claims 4000000000 bytes from"},
      {"npz_central_directory_past_end.npz", StatusCode::kInvalidArgument,
       "the central directory (56 bytes at offset 3000) runs past the end of the archive"},
  };
  for (const Case& c : cases) {
    const std::string path = absl::StrCat(SHAPEID_SOURCE_DIR, "/tests/bad_input/testdata/", c.file);
    ExpectError(ReadPointCloud(path), c.code, path, c.where);
  }
}

// numpy itself writes the files, when the machine has it (Debian's python3-numpy).
TEST(NpyReaderTest, FilesWrittenByNumpy) {
  if (access("/usr/bin/python3", X_OK) != 0 ||
      std::system("/usr/bin/python3 -c 'import numpy' >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "/usr/bin/python3 with numpy is not installed (Debian: python3-numpy)";
  }
  const std::string prefix =
      absl::StrCat(testing::TempDir(), "shapeid_npy_numpy_", ::getpid(), "_");
  // a[i, c] = (4 i + c) / 4 - 100: exact in every dtype written.
  const std::string script = R"(
import sys
import numpy as np
p = sys.argv[1]
a = (np.arange(2000, dtype=np.float64).reshape(500, 4)) * 0.25 - 100.0
np.save(p + "c_f4.npy", a.astype("<f4"))
np.save(p + "f_f8.npy", np.asfortranarray(a.astype(">f8")))
np.save(p + "i4.npy", (a * 4).astype("<i4"))
np.save(p + "grid.npy", a[:, :3].reshape(20, 25, 3).astype("<f4"))
fields = [("intensity", "u1"), ("z", ">f4"), ("y", "<f8"), ("x", "<i2"), ("n", "<f4", (3,))]
s = np.zeros(500, dtype=fields)
s["x"], s["y"], s["z"] = a[:, 0] * 4, a[:, 1], a[:, 2]
np.save(p + "struct.npy", s)
for v in [(1, 0), (2, 0), (3, 0)]:
    with open(p + "v%d.npy" % v[0], "wb") as f:
        np.lib.format.write_array(f, a.astype("<f8"), version=v)
np.savez(p + "stored.npz", a.astype("<f4"), other=np.zeros(3))
np.savez_compressed(p + "deflated.npz", normals=np.zeros((500, 3)), points=a)
)";
  const std::string command = absl::StrCat("/usr/bin/python3 -c '", script, "' ", prefix);
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  struct Case {
    const char* file;
    float scale;  // the file holds scale * a
  };
  for (const Case& c : {Case{"c_f4.npy", 1}, Case{"f_f8.npy", 1}, Case{"i4.npy", 4},
                        Case{"grid.npy", 1}, Case{"v1.npy", 1}, Case{"v2.npy", 1},
                        Case{"v3.npy", 1}, Case{"stored.npz", 1}, Case{"deflated.npz", 1}}) {
    SCOPED_TRACE(c.file);
    const absl::StatusOr<ReadResult> r = ReadPointCloud(prefix + c.file, Raw());
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_EQ(r->cloud.size(), 500u);
    for (size_t i = 0; i < 500; ++i) {
      const float b = static_cast<float>(4 * i);
      ExpectPoint(r->cloud, i, c.scale * (b / 4 - 100), c.scale * ((b + 1) / 4 - 100),
                  c.scale * ((b + 2) / 4 - 100));
    }
  }
  const absl::StatusOr<ReadResult> r = ReadPointCloud(prefix + "struct.npy", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 500u);
  for (size_t i = 0; i < 500; ++i) {
    const float b = static_cast<float>(4 * i);
    ExpectPoint(r->cloud, i, b - 400, (b + 1) / 4 - 100, (b + 2) / 4 - 100);
  }
}

}  // namespace
}  // namespace shapeid
