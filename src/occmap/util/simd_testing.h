// Tests of fast kernels: a gtest fixture run once per kernel set (util/simd.h), skipped for the
// sets this CPU or build lacks, the process's set restored after each test.
//
//   class MyKernels : public KernelSetTest {};
//   INSTANTIATE_TEST_SUITE_P(KernelSets, MyKernels, ::testing::Values("portable", "avx2"));
//   TEST_P(MyKernels, FastEqualsReference) { ... }
#pragma once

#include <gtest/gtest.h>

#include "occmap/util/simd.h"

namespace occmap {

class KernelSetTest : public ::testing::TestWithParam<const char*> {
 protected:
  void SetUp() override {
    if (!ForceKernelsForTesting(GetParam())) GTEST_SKIP() << GetParam() << " not supported here";
  }
  void TearDown() override { ForceKernelsForTesting("best"); }
};

}  // namespace occmap
