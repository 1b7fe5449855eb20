#ifndef SHAPEID_CORE_DESCRIPTORS_COMSD_H_
#define SHAPEID_CORE_DESCRIPTORS_COMSD_H_

#include "core/descriptor_registry.h"

namespace shapeid {

// Registry entry (placeholder until implemented).
DescriptorKind ComsdKind();

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_COMSD_H_
