#include "core/descriptors/cnsd.h"
#include "gtest/gtest.h"
