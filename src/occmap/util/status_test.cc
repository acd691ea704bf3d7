#include "occmap/util/status.h"

#include <gtest/gtest.h>

namespace occmap {
namespace {

Result<int> Half(int x) {
  if (x % 2 != 0) return InvalidInput("x: expected an even number, found " + std::to_string(x));
  return x / 2;
}

Result<int> Quarter(int x) {
  OCCMAP_ASSIGN_OR_RETURN(int h, Half(x));
  OCCMAP_ASSIGN_OR_RETURN(int q, Half(h));
  return q;
}

TEST(Status, OkByDefault) {
  Status s;
  EXPECT_TRUE(s.ok());
  EXPECT_EQ(ExitCodeFor(s), 0);
}

TEST(Status, BadInputMapsToExitCodeTwo) {
  EXPECT_EQ(ExitCodeFor(InvalidInput("x")), 2);
  EXPECT_EQ(ExitCodeFor(NotFound("x")), 2);
  EXPECT_EQ(ExitCodeFor(DataLoss("x")), 2);
  EXPECT_EQ(ExitCodeFor(ResourceExhausted("x")), 2);
  EXPECT_EQ(ExitCodeFor(IoError("x")), 1);
}

TEST(Status, WithContextPrefixesMessage) {
  EXPECT_EQ(InvalidInput("bad").WithContext("site.yaml:3").message(), "site.yaml:3: bad");
}

TEST(Result, PropagatesTheFirstError) {
  EXPECT_EQ(*Quarter(8), 2);
  const Result<int> r = Quarter(6);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "x: expected an even number, found 3");
}

TEST(ResultDeathTest, ValueOfErrorAborts) {
  EXPECT_DEATH({ (void)Quarter(3).value(); }, "expected an even number");
}

}  // namespace
}  // namespace occmap
