#ifndef SHAPEID_CORE_DESCRIPTORS_RPHSD_H_
#define SHAPEID_CORE_DESCRIPTORS_RPHSD_H_
#include "core/descriptor_registry.h"
namespace shapeid {
DescriptorKind RphsdKind();
}  // namespace shapeid
#endif  // SHAPEID_CORE_DESCRIPTORS_RPHSD_H_
