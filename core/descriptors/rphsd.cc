#include "core/descriptors/rphsd.h"
namespace shapeid {
DescriptorKind RphsdKind() {
  return {"rphsd", "placeholder", {}, [](const DescriptorSpec&) -> absl::StatusOr<std::unique_ptr<Descriptor>> {
            return absl::UnimplementedError("rphsd is not implemented yet");
          }};
}
}  // namespace shapeid
