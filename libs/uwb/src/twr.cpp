#include "uwbloc/uwb/twr.hpp"

namespace uwbloc::uwb {

int64_t elapsedTicks(int64_t later, int64_t earlier, int bits) {
  const uint64_t mask = bits >= 64 ? ~uint64_t{0} : ((uint64_t{1} << bits) - 1);
  const uint64_t diff = (static_cast<uint64_t>(later) - static_cast<uint64_t>(earlier)) & mask;
  return static_cast<int64_t>(diff);
}

double singleSidedTwr(double t_round_s, double t_reply_s, double antenna_delay_s) {
  // Eq. (1): half the round trip less the responder's turnaround and the antenna delays.
  return kSpeedOfLight * (t_round_s - t_reply_s - antenna_delay_s) / 2.0;
}

double doubleSidedTwr(double ra_s, double rb_s, double da_s, double db_s, double antenna_delay_s) {
  // Asymmetric DS-TWR: the clock-drift terms cancel to first order.
  const double tof = (ra_s * rb_s - da_s * db_s) / (ra_s + rb_s + da_s + db_s);
  return kSpeedOfLight * (tof - antenna_delay_s / 2.0);
}

}  // namespace uwbloc::uwb
