#include "occmap/util/simd.h"

#include <gtest/gtest.h>

namespace occmap {
namespace {

TEST(KernelSets, NamesRoundTrip) {
  for (KernelSet set : {KernelSet::kPortable, KernelSet::kAvx2, KernelSet::kAvx512}) {
    EXPECT_EQ(ParseKernelSet(KernelSetName(set)), set);
  }
  EXPECT_EQ(ParseKernelSet("avx512bw"), KernelSet::kAvx512);
  EXPECT_EQ(ParseKernelSet("neon"), std::nullopt);
}

TEST(KernelSets, PortableIsAlwaysThereAndCanBeForced) {
  EXPECT_TRUE(KernelsSupported(KernelSet::kPortable));
  ASSERT_TRUE(ForceKernelsForTesting("portable"));
  EXPECT_EQ(ActiveKernels(), KernelSet::kPortable);
  ASSERT_TRUE(ForceKernelsForTesting("best"));
  EXPECT_EQ(ActiveKernels(), BestKernels());
  EXPECT_FALSE(ForceKernelsForTesting("sse9"));
  EXPECT_EQ(ActiveKernels(), BestKernels());
}

TEST(KernelSets, BestIsSupportedAndX86SetsOnlyInX86Builds) {
  EXPECT_TRUE(KernelsSupported(BestKernels()));
#if !OCCMAP_X86_KERNELS
  EXPECT_EQ(BestKernels(), KernelSet::kPortable);
  EXPECT_FALSE(ForceKernelsForTesting("avx2"));
#endif
}

TEST(KernelSets, SettingNamesTheVariableAndFallsBackWithANote) {
  std::string note;
  const Result<KernelSet> bad = KernelsForSetting("avx3", &note);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().message(), "OCCMAP_KERNELS: expected portable, avx2, avx512 or best, found 'avx3'");
  EXPECT_EQ(KernelsForSetting("", &note).value(), BestKernels());
  EXPECT_EQ(KernelsForSetting("portable", &note).value(), KernelSet::kPortable);
  EXPECT_TRUE(note.empty());
  const KernelSet avx512 = KernelsForSetting("avx512", &note).value();
  EXPECT_TRUE(KernelsSupported(avx512));
  if (!KernelsSupported(KernelSet::kAvx512)) {
    EXPECT_NE(note.find("OCCMAP_KERNELS=avx512: not supported"), std::string::npos) << note;
  } else {
    EXPECT_TRUE(note.empty());
  }
}

}  // namespace
}  // namespace occmap
