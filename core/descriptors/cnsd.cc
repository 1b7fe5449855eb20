#include "core/descriptors/cnsd.h"

namespace shapeid {

DescriptorKind CnsdKind() {
  return {"cnsd", "placeholder", {}, [](const DescriptorSpec&) -> absl::StatusOr<std::unique_ptr<Descriptor>> {
            return absl::UnimplementedError("cnsd is not implemented yet");
          }};
}

}  // namespace shapeid
