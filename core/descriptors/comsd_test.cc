#include "core/descriptors/comsd.h"
#include "gtest/gtest.h"
