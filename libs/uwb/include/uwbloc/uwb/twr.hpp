// Two-way time-of-flight ranging from raw device timestamps.
#pragma once

#include <cstdint>

namespace uwbloc::uwb {

constexpr double kSpeedOfLight = 299702547.0;  ///< in air [m/s], as DW1000 firmware uses
/// One DW1000 time unit: 1 / (128 * 499.2 MHz) [s], about 15.65 ps.
constexpr double kDw1000Tick = 1.0 / (128.0 * 499.2e6);

/// Elapsed ticks from `earlier` to `later` on a free-running counter of `bits` bits,
/// so that a wrap-around between the two readings is handled. Inputs may be stored as signed
/// (as exported logs often do); only their low `bits` bits matter.
int64_t elapsedTicks(int64_t later, int64_t earlier, int bits = 40);

/// Single-sided TW-TOF, the PF-IBAS paper's eq. (1):
///   d = c (T_round - T_reply - delta) / 2
/// with T_round the initiator's poll-to-response time, T_reply the responder's turnaround and
/// delta the summed antenna delays, all in seconds.
double singleSidedTwr(double t_round_s, double t_reply_s, double antenna_delay_s = 0.0);

/// Double-sided (asymmetric) TW-TOF:
///   d = c (Ra Rb - Da Db) / (Ra + Rb + Da + Db) - c delta / 2
/// Ra, Rb: round trips measured by initiator and responder; Da, Db: their reply delays [s].
double doubleSidedTwr(double ra_s, double rb_s, double da_s, double db_s,
                      double antenna_delay_s = 0.0);

}  // namespace uwbloc::uwb
