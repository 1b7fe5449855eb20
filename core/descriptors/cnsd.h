#ifndef SHAPEID_CORE_DESCRIPTORS_CNSD_H_
#define SHAPEID_CORE_DESCRIPTORS_CNSD_H_

#include "core/descriptor_registry.h"

namespace shapeid {

// Registry entry (placeholder until implemented).
DescriptorKind CnsdKind();

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_CNSD_H_
