#include "core/descriptors/reference_points.h"

#include <cmath>
#include <cstdio>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace shapeid {
namespace {

constexpr double kPi = 3.14159265358979323846;

// sin(pi) and friends are ~1e-16 in double, not 0; the published arrangements have exact
// zeros there, and exact zeros keep 90-degree symmetries exact.
float Snap(double v) { return std::fabs(v) < 1e-12 ? 0.0f : static_cast<float>(v); }

std::string FormatFloat(float v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g", static_cast<double>(v));  // round-trips a float
  return buf;
}

absl::StatusOr<ReferenceArrangement> ParseCustom(absl::string_view text) {
  const absl::string_view inner = text.substr(1, text.size() - 2);
  ReferenceArrangement arrangement;
  std::string canonical = "[";
  for (absl::string_view point_text : absl::StrSplit(inner, ';')) {
    std::vector<absl::string_view> coords = absl::StrSplit(point_text, ',');
    if (coords.size() != 3) {
      return absl::InvalidArgumentError(absl::StrCat("rphsd: reference point \"", point_text,
                                                     "\" in ", text, " needs 3 coordinates x,y,z"));
    }
    Eigen::Vector3f p;
    for (int a = 0; a < 3; ++a) {
      float v = 0;
      if (!absl::SimpleAtof(absl::StripAsciiWhitespace(coords[a]), &v) || !std::isfinite(v) ||
          std::fabs(v) > kMaxReferenceCoordinate) {
        return absl::InvalidArgumentError(
            absl::StrCat("rphsd: coordinate \"", coords[a], "\" of reference point \"", point_text,
                         "\" is not a number in [-", kMaxReferenceCoordinate, ", ",
                         kMaxReferenceCoordinate, "]"));
      }
      p[a] = v;
    }
    if (arrangement.points.size() == kMaxReferencePoints) {
      return absl::InvalidArgumentError(
          absl::StrCat("rphsd: more than ", kMaxReferencePoints, " reference points"));
    }
    absl::StrAppend(&canonical, arrangement.points.empty() ? "" : ";", FormatFloat(p.x()), ",",
                    FormatFloat(p.y()), ",", FormatFloat(p.z()));
    arrangement.points.push_back(p);
  }
  arrangement.name = canonical + "]";
  return arrangement;
}

}  // namespace

std::vector<Eigen::Vector3f> Cross7References() {
  return {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, {0, 0, 0}};
}

std::vector<Eigen::Vector3f> Cubic27References() {
  std::vector<Eigen::Vector3f> points;
  for (int x = -1; x <= 1; ++x) {
    for (int y = -1; y <= 1; ++y) {
      for (int z = -1; z <= 1; ++z) points.emplace_back(x, y, z);
    }
  }
  return points;
}

std::vector<Eigen::Vector3f> Spherical27References() {
  // The published arrangement takes psi in degrees; the author's code passed the numbers as
  // radians (rings at +-58.31 degrees). We follow the text.
  std::vector<Eigen::Vector3f> points;
  for (int psi_deg : {-45, 0, 45}) {
    const double psi = psi_deg * kPi / 180.0;
    for (int theta_deg = 0; theta_deg < 360; theta_deg += 45) {
      const double theta = theta_deg * kPi / 180.0;
      points.emplace_back(Snap(std::sin(theta) * std::sin(psi)), Snap(std::cos(theta)),
                          Snap(std::sin(theta) * std::cos(psi)));
    }
  }
  points.emplace_back(0, 0, 0);
  points.emplace_back(0, -1, 0);
  points.emplace_back(0, 1, 0);
  return points;
}

std::vector<Eigen::Vector3f> FibonacciReferences(int n) {
  std::vector<Eigen::Vector3f> points = {{0, 0, 0}};
  const double golden_angle = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(1.0 - z * z);
    const double phi = i * golden_angle;
    points.emplace_back(Snap(r * std::cos(phi)), Snap(r * std::sin(phi)), Snap(z));
  }
  return points;
}

absl::StatusOr<ReferenceArrangement> ParseReferenceArrangement(absl::string_view text) {
  text = absl::StripAsciiWhitespace(text);
  const std::string lower = absl::AsciiStrToLower(text);
  if (lower == "cross7") return ReferenceArrangement{"cross7", Cross7References()};
  if (lower == "cubic27") return ReferenceArrangement{"cubic27", Cubic27References()};
  if (lower == "spherical27") return ReferenceArrangement{"spherical27", Spherical27References()};
  if (absl::StartsWith(lower, "fibonacci:")) {
    int n = 0;
    if (!absl::SimpleAtoi(absl::string_view(lower).substr(10), &n) || n < 1 ||
        n > kMaxReferencePoints - 1) {
      return absl::InvalidArgumentError(absl::StrCat(
          "rphsd: refs=", text, ": fibonacci:N needs N in [1, ", kMaxReferencePoints - 1, "]"));
    }
    return ReferenceArrangement{absl::StrCat("fibonacci:", n), FibonacciReferences(n)};
  }
  if (text.size() >= 2 && text.front() == '[' && text.back() == ']') return ParseCustom(text);
  return absl::InvalidArgumentError(absl::StrCat("rphsd: refs=", text,
                                                 " is not an arrangement; use cross7, cubic27, "
                                                 "spherical27, fibonacci:N or [x,y,z;x,y,z;...]"));
}

}  // namespace shapeid
