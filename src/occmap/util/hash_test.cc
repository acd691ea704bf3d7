#include "occmap/util/hash.h"

#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

namespace occmap {
namespace {

constexpr uint64_t kGoldenDigest = 1057443627228820761ULL;

TEST(Hasher, IsDeterministic) {
  Hasher a, b;
  a.Add("lut");
  a.AddPod(0.025);
  b.Add("lut");
  b.AddPod(0.025);
  EXPECT_EQ(a.Digest(), b.Digest());
}

TEST(Hasher, StableAcrossReleases) {
  // Cache keys are stored in files: a change of this value invalidates every saved table, so
  // it must come with a bump of the file format versions.
  Hasher h;
  h.Add("occmap");
  h.AddPod(0.025);
  EXPECT_EQ(h.Digest(), kGoldenDigest);
}

TEST(Hasher, EverySingleBitFlipChangesTheDigest) {
  std::vector<unsigned char> data(1000);
  for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<unsigned char>(i * 7);
  std::set<uint64_t> digests;
  digests.insert(HashBytes(std::as_bytes(std::span(data))));
  for (size_t i = 0; i < data.size(); i += 13) {
    for (int bit = 0; bit < 8; ++bit) {
      auto copy = data;
      copy[i] ^= static_cast<unsigned char>(1u << bit);
      digests.insert(HashBytes(std::as_bytes(std::span(copy))));
    }
  }
  EXPECT_EQ(digests.size(), 1 + 8 * ((data.size() + 12) / 13));
}

TEST(Hasher, LengthMatters) {
  std::vector<unsigned char> zeros(64, 0);
  EXPECT_NE(HashBytes(std::as_bytes(std::span(zeros.data(), 32))),
            HashBytes(std::as_bytes(std::span(zeros.data(), 33))));
  Hasher a, b;
  a.Add("ab");
  a.Add("c");
  b.Add("a");
  b.Add("bc");
  EXPECT_NE(a.Digest(), b.Digest());
}

}  // namespace
}  // namespace occmap
