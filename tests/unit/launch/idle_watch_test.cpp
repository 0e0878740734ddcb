// IdleWatch on made-up CPU ticks (100 a second): idle once the processes
// together stay under 5 % of a core for the whole idle time; a busy
// sample or a process that appears starts the count again.

#include <gtest/gtest.h>

#include "vloc/launch/idle_watch.h"

namespace vloc {
namespace {

TEST(IdleWatch, IdleOnlyAfterTheWholeTimeUnderTheThreshold) {
  IdleWatch idle(/*idle_s=*/1.0, /*ticks_per_second=*/100);
  std::map<pid_t, uint64_t> ticks = {{10, 500}, {11, 40}};
  EXPECT_FALSE(idle.Update(0.0, ticks));
  ticks[10] += 40;  // 0.4 s of CPU in 0.5 s: busy
  EXPECT_FALSE(idle.Update(0.5, ticks));
  ticks[11] += 2;  // 0.02 s in 0.5 s = 4 %: idle from here
  EXPECT_FALSE(idle.Update(1.0, ticks));
  ticks[10] += 1;
  EXPECT_FALSE(idle.Update(1.4, ticks));
  EXPECT_TRUE(idle.Update(1.6, ticks));  // idle since 0.5 s
}

TEST(IdleWatch, ABusySampleOrANewProcessStartsTheCountAgain) {
  IdleWatch idle(1.0, 100);
  std::map<pid_t, uint64_t> ticks = {{10, 0}};
  EXPECT_FALSE(idle.Update(0.0, ticks));
  EXPECT_FALSE(idle.Update(0.6, ticks));
  ticks[10] += 4;  // 0.04 s in 0.3 s = 13 %
  EXPECT_FALSE(idle.Update(0.9, ticks));
  EXPECT_FALSE(idle.Update(1.8, ticks));
  ticks[12] = 1;  // a process that appeared: all its time counts, 0.01 s in 0.1 s = 10 %
  EXPECT_FALSE(idle.Update(1.9, ticks));
  EXPECT_FALSE(idle.Update(2.8, ticks));
  EXPECT_TRUE(idle.Update(3.0, ticks));
  ticks.erase(10);  // a process that ended is no work
  EXPECT_TRUE(idle.Update(3.1, ticks));
  EXPECT_FALSE(idle.Update(3.2, ticks, /*start_pending=*/true));  // one about to restart
  EXPECT_FALSE(idle.Update(4.1, ticks));
  EXPECT_TRUE(idle.Update(4.3, ticks));
}

}  // namespace
}  // namespace vloc
