#ifndef SHAPEID_SERVER_SERVICE_OPTIONS_H_
#define SHAPEID_SERVER_SERVICE_OPTIONS_H_

#include <cstddef>
#include <string>

#include "core/descriptor_registry.h"

namespace shapeid {

// What the ShapeId service accepts. Defaults suit a shared lab server; main.cc maps flags
// (and SHAPEID_* environment variables) onto these.
struct ServiceOptions {
  // Largest cloud, in points, any RPC accepts. 10 million points is 120 MB on the wire and a
  // few seconds of describing: enough for a dense scan, small enough that one client cannot
  // exhaust the server's memory.
  size_t max_points_per_cloud = 10'000'000;
  // Spec used by Describe when neither a spec nor a gallery is given.
  std::string default_descriptor_spec = kDefaultDescriptorSpec;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SERVICE_OPTIONS_H_
