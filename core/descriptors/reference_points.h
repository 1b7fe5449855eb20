#ifndef SHAPEID_CORE_DESCRIPTORS_REFERENCE_POINTS_H_
#define SHAPEID_CORE_DESCRIPTORS_REFERENCE_POINTS_H_

#include <string>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// Reference points for RPHSD, in the normalized frame where the cloud lies in [-1, 1]^3
// (docs/descriptors.md, RPHSD step 5 and dissertation figure 36).
struct ReferenceArrangement {
  std::string name;  // canonical text: cross7 | cubic27 | spherical27 | fibonacci:N | [x,y,z;...]
  std::vector<Eigen::Vector3f> points;
};

// Parses the text of the `refs` parameter. Custom lists are "[x,y,z;x,y,z;...]" with 1 to
// kMaxReferencePoints points whose coordinates lie in [-kMaxReferenceCoordinate,
// kMaxReferenceCoordinate]. Errors are InvalidArgument and quote the bad part.
absl::StatusOr<ReferenceArrangement> ParseReferenceArrangement(absl::string_view text);

inline constexpr int kMaxReferencePoints = 4096;
// References far outside the unit cube all see the cloud in the last bin; the bound also keeps
// the bin arithmetic far from integer overflow.
inline constexpr float kMaxReferenceCoordinate = 100.0f;

// A1: the six axis points and the origin.
std::vector<Eigen::Vector3f> Cross7References();
// A3: all of {-1, 0, 1}^3, x outermost, z innermost.
std::vector<Eigen::Vector3f> Cubic27References();
// A2: three rings at psi = -45, 0, 45 degrees of eight points each, then the origin and poles.
std::vector<Eigen::Vector3f> Spherical27References();
// The origin, then n points of the Fibonacci sphere of radius 1.
std::vector<Eigen::Vector3f> FibonacciReferences(int n);

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_REFERENCE_POINTS_H_
