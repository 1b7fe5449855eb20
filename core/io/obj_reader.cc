#include "core/io/obj_reader.h"

#include <cstdint>
#include <istream>
#include <streambuf>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/io/cloud_accumulator.h"
#include "core/io/mesh_sampler.h"
#include "core/io/text_lines.h"
#include "core/status_macros.h"
#include "tiny_obj_loader.h"

namespace shapeid {
namespace {

// A read-only stream buffer over the caller's bytes: tinyobjloader parses them in place, and
// because it calls back only after reading a whole line, the read position tells a callback
// where its line ends. std::streambuf never writes to a get area (putting back a different
// character goes through pbackfail, which refuses), so the const_cast is safe.
class ViewBuf : public std::streambuf {
 public:
  explicit ViewBuf(absl::string_view text) {
    char* begin = const_cast<char*>(text.data());
    setg(begin, begin, begin + text.size());
  }
  size_t offset() const { return static_cast<size_t>(gptr() - eback()); }
  // Makes the stream end here, so that parsing stops after the current line.
  void Stop() { setg(eback(), egptr(), egptr()); }
};

// The state that tinyobjloader's callbacks fill. The callback API reports no errors of its own
// (it hands over raw indices and returns true), so every check is made here.
class ObjParser {
 public:
  ObjParser(absl::string_view contents, absl::string_view name)
      : contents_(contents), name_(name), buf_(contents) {}

  absl::StatusOr<ReadResult> Parse(const ReadOptions& options) &&;

 private:
  struct Line {
    uint64_t number;
    absl::string_view text;
  };

  static void OnVertex(void* self, tinyobj::real_t, tinyobj::real_t, tinyobj::real_t,
                       tinyobj::real_t) {
    static_cast<ObjParser*>(self)->AddVertex();
  }
  static void OnFace(void* self, tinyobj::index_t* indices, int count) {
    static_cast<ObjParser*>(self)->AddFace(indices, count);
  }

  void AddVertex();
  void AddFace(const tinyobj::index_t* indices, int count);
  // The line tinyobjloader is handling, which ends at the read position.
  Line CurrentLine();
  // Records the first error and stops the parse.
  void Fail(uint64_t line, absl::string_view message);

  absl::string_view contents_;
  absl::string_view name_;
  ViewBuf buf_;
  absl::Status status_;

  // Line numbering, advanced incrementally as the callbacks move through the file.
  size_t counted_to_ = 0;
  uint64_t lines_before_ = 0;

  std::vector<double> xyz_;
  std::vector<uint64_t> vertex_lines_;
  TriangleMesh mesh_;
  std::vector<uint64_t> face_;
  // Positive indices may refer forward (tinyobjloader allows it too), so the largest one is
  // checked against the vertex count once the whole file is read.
  uint64_t max_index_ = 0;
  uint64_t max_index_line_ = 0;
  bool any_positive_index_ = false;
};

ObjParser::Line ObjParser::CurrentLine() {
  // tinyobjloader ends a line at "\n", "\r\n" or a lone "\r" (its safeGetline); so does this.
  size_t end = buf_.offset();
  if (end > 0 && contents_[end - 1] == '\n') {
    --end;
    if (end > 0 && contents_[end - 1] == '\r') --end;
  } else if (end > 0 && contents_[end - 1] == '\r') {
    --end;
  }
  size_t start = end;
  while (start > 0 && contents_[start - 1] != '\n' && contents_[start - 1] != '\r') --start;
  for (size_t i = counted_to_; i < start; ++i) {
    const char c = contents_[i];
    if (c == '\n' || (c == '\r' && (i + 1 == contents_.size() || contents_[i + 1] != '\n'))) {
      ++lines_before_;
    }
  }
  counted_to_ = start;
  return Line{lines_before_ + 1, contents_.substr(start, end - start)};
}

void ObjParser::Fail(uint64_t line, absl::string_view message) {
  status_ = absl::InvalidArgumentError(absl::StrCat(name_, ": line ", line, ": ", message));
  buf_.Stop();
}

void ObjParser::AddVertex() {
  if (!status_.ok()) return;
  const Line line = CurrentLine();
  // tinyobjloader reads a coordinate it cannot parse (or a missing one) as 0, which would put a
  // truncated or garbled vertex silently at the origin; so the line's coordinates are read
  // again here, with the number parser of the other readers ("nan" and "inf" included).
  Tokenizer tokens(line.text);
  absl::string_view token;
  tokens.Next(&token);  // "v"
  double v[3];
  for (int a = 0; a < 3; ++a) {
    if (!tokens.Next(&token)) {
      return Fail(line.number, absl::StrCat("a vertex needs x y z, found ", a, " values in ",
                                            QuoteForMessage(line.text)));
    }
    if (!absl::SimpleAtod(token, &v[a])) {
      return Fail(line.number, absl::StrCat(std::string(1, "xyz"[a]), " value ",
                                            QuoteForMessage(token), " is not a number"));
    }
  }
  xyz_.insert(xyz_.end(), v, v + 3);
  vertex_lines_.push_back(line.number);
}

void ObjParser::AddFace(const tinyobj::index_t* indices, int count) {
  if (!status_.ok()) return;
  const Line line = CurrentLine();
  if (count < 3) {
    return Fail(line.number, absl::StrCat("a face needs 3 or more vertices, found ", count, " in ",
                                          QuoteForMessage(line.text)));
  }
  const uint64_t vertices = xyz_.size() / 3;
  face_.clear();
  for (int k = 0; k < count; ++k) {
    // Raw, as written: 1-based, negative counts back from the last vertex so far, and 0 for an
    // index that is 0 or not a number (tinyobjloader reads it with atoi).
    const int64_t raw = indices[k].vertex_index;
    uint64_t index = 0;
    if (raw > 0) {
      index = static_cast<uint64_t>(raw - 1);
      if (!any_positive_index_ || index > max_index_) {
        max_index_ = index;
        max_index_line_ = line.number;
        any_positive_index_ = true;
      }
    } else if (raw < 0 && static_cast<uint64_t>(-raw) <= vertices) {
      index = vertices - static_cast<uint64_t>(-raw);
    } else {
      return Fail(line.number,
                  raw == 0
                      ? absl::StrCat("face vertex ", k + 1, " is 0 or not a number in ",
                                     QuoteForMessage(line.text), "; OBJ indices start at 1")
                      : absl::StrCat("relative vertex index ", raw, " reaches before the first of ",
                                     vertices, " vertices read so far"));
    }
    face_.push_back(index);
  }
  mesh_.AddPolygon(face_, line.number);
}

absl::StatusOr<ReadResult> ObjParser::Parse(const ReadOptions& options) && {
  if (contents_.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(name_, ": the file is empty"));
  }
  tinyobj::callback_t callbacks;
  callbacks.vertex_cb = &ObjParser::OnVertex;
  callbacks.index_cb = &ObjParser::OnFace;
  std::istream stream(&buf_);
  std::string error;
  // No MaterialReader: `mtllib` lines are skipped without opening anything.
  const bool parsed = tinyobj::LoadObjWithCallback(stream, callbacks, this, /*readMatFn=*/nullptr,
                                                   /*warn=*/nullptr, &error);
  SHAPEID_RETURN_IF_ERROR(status_);
  if (!parsed) {
    return absl::InvalidArgumentError(absl::StrCat(name_, ": tinyobjloader: ", error));
  }
  const uint64_t vertices = xyz_.size() / 3;
  if (vertices == 0) {
    return absl::InvalidArgumentError(
        absl::StrCat(name_, ": no vertex (\"v x y z\") lines; is this an OBJ file?"));
  }
  if (any_positive_index_ && max_index_ >= vertices) {
    return absl::InvalidArgumentError(
        absl::StrCat(name_, ": line ", max_index_line_, ": vertex index ", max_index_ + 1,
                     " is out of range; the file has ", vertices, " vertices"));
  }

  CloudAccumulator cloud(name_, "line");
  if (options.sample_points > 0 && mesh_.triangle_count() > 0) {
    for (uint64_t i = 0; i < vertices; ++i) {
      mesh_.AddVertex(xyz_[3 * i], xyz_[3 * i + 1], xyz_[3 * i + 2]);
    }
    SHAPEID_RETURN_IF_ERROR(
        mesh_.Sample(options.sample_points, options.sample_seed, name_, "line", &cloud));
  } else {
    cloud.Reserve(vertices);
    for (uint64_t i = 0; i < vertices; ++i) {
      cloud.Add(xyz_[3 * i], xyz_[3 * i + 1], xyz_[3 * i + 2], vertex_lines_[i]);
    }
  }
  return std::move(cloud).Finish(options);
}

}  // namespace

absl::StatusOr<ReadResult> ParseObj(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options) {
  return ObjParser(contents, name).Parse(options);
}

}  // namespace shapeid
