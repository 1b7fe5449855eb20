#include "core/descriptors/comsd.h"

namespace shapeid {

DescriptorKind ComsdKind() {
  return {"comsd", "placeholder", {}, [](const DescriptorSpec&) -> absl::StatusOr<std::unique_ptr<Descriptor>> {
            return absl::UnimplementedError("comsd is not implemented yet");
          }};
}

}  // namespace shapeid
