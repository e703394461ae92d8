#include "uwbloc/dataset/rawlog.hpp"

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationBeaconRanges.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>

#include <algorithm>
#include <filesystem>
#include <sstream>

#include "mrpt_scan.hpp"
#include "odometry_poses.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/memory_limits.hpp"
#include "uwbloc/dataset/text_io.hpp"

namespace uwbloc::data {

namespace {

using mrpt::obs::CObservation;

// Ranges of the robot's own tag carry the label "UWB"; another tag k writes "UWB_TAG<k>".
int tagIdFromLabel(const std::string& label) {
  const std::string prefix = "UWB_TAG";
  if (label.rfind(prefix, 0) != 0) return 0;
  try {
    return std::stoi(label.substr(prefix.size()));
  } catch (const std::exception&) {
    return 0;
  }
}

// CObservationIMU::has() and get() read the deserialised flag as a bool (undefined for a byte
// other than 0 or 1, as a corrupt rawlog may hold): neither is used.
bool imuHas(const mrpt::obs::CObservationIMU& imu, mrpt::obs::TIMUDataIndex idx) {
  const auto i = static_cast<size_t>(idx);
  return i < imu.dataIsPresent.size() && byteAsBool(imu.dataIsPresent[i]);
}

double toSeconds(mrpt::Clock::time_point t) {
  return t == INVALID_TIMESTAMP ? 0.0 : mrpt::Clock::toDouble(t);
}

class Converter {
 public:
  explicit Converter(Recording& rec) : rec_(rec) {}

  // Converts one observation; `fallback_t` is used when it carries no timestamp.
  void observation(const CObservation& obs, double fallback_t) {
    double t = toSeconds(obs.timestamp);
    if (t == 0.0) {
      t = fallback_t;
      ++rec_.counts["timestamp_from_frame"];
    }
    if (const char* problem = timestampProblem(t)) {
      ++rec_.counts[std::string("rejected_") + problem];
      return;
    }
    last_t_ = std::max(last_t_, t);
    if (const auto* b = dynamic_cast<const mrpt::obs::CObservationBeaconRanges*>(&obs)) {
      for (const auto& m : b->sensedData) {
        uwb::Range r;
        r.t = t;
        r.anchor_id = static_cast<int>(m.beaconID);
        r.tag_id = tagIdFromLabel(b->sensorLabel);
        r.on_robot = r.tag_id == 0;
        r.range = m.sensedDistance;
        r.tag_on_robot << m.sensorLocationOnRobot.x(), m.sensorLocationOnRobot.y(),
            m.sensorLocationOnRobot.z();
        rec_.events.emplace_back(r);
      }
      ++rec_.counts["beacon_observations"];
    } else if (const auto* s = dynamic_cast<const mrpt::obs::CObservation2DRangeScan*>(&obs)) {
      loc::LaserScan scan = fromMrpt(*s, t);
      rec_.events.emplace_back(std::move(scan));
      ++rec_.counts["scans"];
    } else if (const auto* imu = dynamic_cast<const mrpt::obs::CObservationIMU*>(&obs)) {
      using namespace mrpt::obs;
      if (!imuHas(*imu, IMU_X_ACC) || !imuHas(*imu, IMU_Y_ACC) || !imuHas(*imu, IMU_YAW_VEL)) {
        ++rec_.counts["rejected_imu_without_planar_fields"];
        return;
      }
      loc::ImuSample sample;
      sample.t = t;
      sample.accel << imu->rawMeasurements.at(IMU_X_ACC), imu->rawMeasurements.at(IMU_Y_ACC);
      sample.gyro_z = imu->rawMeasurements.at(IMU_YAW_VEL);
      rec_.events.emplace_back(sample);
      ++rec_.counts["imu_observations"];
    } else if (const auto* o = dynamic_cast<const mrpt::obs::CObservationOdometry*>(&obs)) {
      const Eigen::Vector3d pose(o->odometry.x(), o->odometry.y(), o->odometry.phi());
      if (!odometry_.add(t, pose, rec_.events)) {
        ++rec_.counts["rejected_odometry_out_of_order"];
        return;
      }
      ++rec_.counts["odometry_observations"];
    } else {
      ++rec_.counts[std::string("ignored_") + obs.GetRuntimeClass()->className];
    }
  }

  void sensoryFrame(const mrpt::obs::CSensoryFrame& sf) {
    double frame_t = 0.0;
    for (const auto& o : sf)
      if (o && toSeconds(o->timestamp) != 0.0) {
        frame_t = toSeconds(o->timestamp);
        break;
      }
    if (frame_t == 0.0) frame_t = last_t_;
    if (pending_action_) {
      // The action's motion ends at this frame: stamp it so, and count a step.
      pending_action_->t = frame_t;
      rec_.events.emplace_back(*pending_action_);
      pending_action_.reset();
      rec_.step_times.push_back(frame_t);
    }
    for (const auto& o : sf)
      if (o) observation(*o, frame_t);
    ++rec_.counts["sensory_frames"];
  }

  void actions(const mrpt::obs::CActionCollection& acts) {
    ++rec_.counts["actions"];
    const auto move = acts.getBestMovementEstimation();
    if (!move) return;
    const auto mean = move->poseChange->getMeanVal();
    if (const char* problem = timestampProblem(toSeconds(move->timestamp))) {
      ++rec_.counts[std::string("rejected_") + problem];
      return;
    }
    loc::OdometryIncrement inc;
    inc.t = std::max(last_t_, toSeconds(move->timestamp));
    inc.delta << mean.x(), mean.y(), mean.phi();
    pending_action_ = inc;
  }

  void finish() {
    if (pending_action_) rec_.events.emplace_back(*pending_action_);  // trailing action
    loc::sortByTime(rec_.events);
  }

  void observationOnly(const CObservation& obs) {
    const double t = toSeconds(obs.timestamp);
    observation(obs, t == 0.0 ? last_t_ : t);
    rec_.step_times.push_back(t == 0.0 ? last_t_ : t);
  }

 private:
  Recording& rec_;
  double last_t_ = 0.0;
  std::optional<loc::OdometryIncrement> pending_action_;
  OdometryFromPoses odometry_;
};

/// The one-line cause inside an MRPT exception's text (its first "Message:" line, without the
/// nested traces and backtraces), at most 160 characters.
std::string mrptCause(const std::string& what) {
  std::istringstream in(what);
  std::string line;
  while (std::getline(in, line)) {
    const auto at = line.find("Message:");
    if (at == std::string::npos) continue;
    line = line.substr(at + 8);
    const auto first = line.find_first_not_of(' ');
    line = first == std::string::npos ? "" : line.substr(first);
    if (!line.empty()) return line.substr(0, 160);
  }
  const auto end = what.find('\n');
  return what.substr(0, std::min<size_t>(end == std::string::npos ? what.size() : end, 160));
}

/// The length of the (uncompressed) stream: one pass through it, which also finds a gzip stream
/// that was cut off.
uint64_t streamLength(const std::string& path) {
  mrpt::io::CFileGZInputStream in;
  if (!in.open(path)) throwInputError(path, 0, "cannot open rawlog");
  std::vector<char> buffer(1 << 20);
  uint64_t total = 0;
  try {
    for (;;) {
      // gzread's -1 (a damaged or cut-off gzip stream) arrives here as SIZE_MAX.
      const size_t n = in.Read(buffer.data(), buffer.size());
      if (n > buffer.size()) throw std::runtime_error("the gzip stream is damaged or cut off");
      total += n;
      if (n < buffer.size()) break;
    }
  } catch (const std::exception& e) {
    throwInputError(path, 0,
                    "corrupt compressed stream after " + std::to_string(total) +
                        " bytes: " + mrptCause(e.what()));
  }
  return total;
}

/// What deserialising the object at `position` may allocate: a count or a string length read
/// from the stream cannot describe more than what is left of it (16 bytes in memory per byte in
/// the stream, a 64 MiB floor), nor more than the memory budget.
size_t objectAllocationCap(uint64_t length, uint64_t position) {
  const uint64_t left = length > position ? length - position : 0;
  const uint64_t cap = std::max<uint64_t>(64ull << 20, 16 * left);
  return static_cast<size_t>(std::min<uint64_t>(cap, memoryBudget()));
}

}  // namespace

Recording readRawlogInProcess(const std::string& path, RawlogProgress* progress) {
  requireRegularFile(path);
  const uint64_t length = streamLength(path);
  mrpt::io::CFileGZInputStream in;
  if (!in.open(path)) throwInputError(path, 0, "cannot open rawlog");
  auto archive = mrpt::serialization::archiveFrom(in);
  Recording rec;
  Converter conv(rec);
  long objects = 0;
  for (;;) {
    mrpt::serialization::CSerializable::Ptr obj;
    const uint64_t position = in.getPosition();
    if (progress) {
      progress->objects = static_cast<uint64_t>(objects);
      progress->position = position;
    }
    // The cap covers MRPT's reading only; what it refused is kept for the message, which is
    // composed after the cap has ended.
    size_t claimed = 0;
    auto readCapped = [&] {
      const ScopedAllocationCap cap(objectAllocationCap(length, position));
      try {
        return archive.ReadObject();
      } catch (...) {
        if (cap.refused() != 0) claimed = cap.used() + cap.refused();
        throw;
      }
    };
    try {
      obj = readCapped();
    } catch (const mrpt::serialization::CExceptionEOF&) {
      // A clean end of file: nothing of a next object was read.
      if (in.checkEOF()) break;
      throwInputError(path, 0, "truncated rawlog after " + std::to_string(objects) + " objects");
    } catch (const std::exception& e) {
      // MRPT wraps what a nested object throws: the cap's refusal is read from `claimed`.
      const std::string cause =
          claimed != 0
              ? "it claims " + formatBytes(static_cast<double>(claimed)) + ", more than the " +
                    formatBytes(static_cast<double>(length - position)) +
                    " left in the stream can describe (a corrupt count or length)"
              : mrptCause(e.what());
      throwInputError(path, 0,
                      "corrupt or truncated rawlog: object " + std::to_string(objects + 1) +
                          " (at byte " + std::to_string(position) +
                          " of the uncompressed stream) cannot be read: " + cause);
    }
    ++objects;
    if (!obj) continue;
    try {
      if (const auto sf = std::dynamic_pointer_cast<mrpt::obs::CSensoryFrame>(obj)) {
        conv.sensoryFrame(*sf);
      } else if (const auto acts = std::dynamic_pointer_cast<mrpt::obs::CActionCollection>(obj)) {
        conv.actions(*acts);
      } else if (const auto obs = std::dynamic_pointer_cast<CObservation>(obj)) {
        conv.observationOnly(*obs);
      } else {
        ++rec.counts[std::string("ignored_") + obj->GetRuntimeClass()->className];
      }
    } catch (const std::exception& e) {
      // A well-formed object whose contents MRPT's own accessors refuse.
      throwInputError(path, 0,
                      "rawlog object " + std::to_string(objects) + " (at byte " +
                          std::to_string(position) + ", " + obj->GetRuntimeClass()->className +
                          ") cannot be converted: " + mrptCause(e.what()));
    }
  }
  if (objects == 0) throwInputError(path, 0, "empty rawlog");
  conv.finish();
  return rec;
}

void writeRawlog(const std::string& path, const std::vector<loc::Event>& events) {
  const std::string tmp = path + ".tmp";
  {
    mrpt::io::CFileGZOutputStream out;
    if (!out.open(tmp)) throwInputError(path, 0, "cannot write rawlog");
    auto archive = mrpt::serialization::archiveFrom(out);
    mrpt::obs::CObservationBeaconRanges::Ptr pending;
    auto flush = [&] {
      if (pending) archive << *pending;
      pending.reset();
    };
    Eigen::Vector3d odometry = Eigen::Vector3d::Zero();
    bool odometry_started = false;
    for (const auto& e : events) {
      if (const auto* r = std::get_if<uwb::Range>(&e)) {
        const auto ts = mrpt::Clock::fromDouble(r->t);
        const std::string label = r->tag_id == 0 ? "UWB" : "UWB_TAG" + std::to_string(r->tag_id);
        if (pending && (pending->timestamp != ts || pending->sensorLabel != label)) flush();
        if (!pending) {
          pending = std::make_shared<mrpt::obs::CObservationBeaconRanges>();
          pending->timestamp = ts;
          pending->sensorLabel = label;
          pending->minSensorDistance = 0;
          pending->maxSensorDistance = 1000;
          pending->stdError = 0.1f;
        }
        mrpt::obs::CObservationBeaconRanges::TMeasurement m;
        m.beaconID = r->anchor_id;
        m.sensedDistance = static_cast<float>(r->range);
        m.sensorLocationOnRobot =
            mrpt::poses::CPoint3D(r->tag_on_robot.x(), r->tag_on_robot.y(), r->tag_on_robot.z());
        pending->sensedData.push_back(m);
        continue;
      }
      flush();
      if (const auto* o = std::get_if<loc::OdometryIncrement>(&e)) {
        mrpt::obs::CObservationOdometry obs;
        obs.timestamp = mrpt::Clock::fromDouble(o->t);
        obs.sensorLabel = "ODOMETRY";
        if (!odometry_started) {
          // The first reading is the origin; increments follow from the next one.
          mrpt::obs::CObservationOdometry origin = obs;
          origin.odometry = mrpt::poses::CPose2D(0, 0, 0);
          archive << origin;
          odometry_started = true;
        }
        odometry = loc::composePose(odometry, o->delta);
        obs.odometry = mrpt::poses::CPose2D(odometry.x(), odometry.y(), odometry.z());
        archive << obs;
      } else if (const auto* imu = std::get_if<loc::ImuSample>(&e)) {
        mrpt::obs::CObservationIMU obs;
        obs.timestamp = mrpt::Clock::fromDouble(imu->t);
        obs.sensorLabel = "IMU";
        obs.set(mrpt::obs::IMU_X_ACC, imu->accel.x());
        obs.set(mrpt::obs::IMU_Y_ACC, imu->accel.y());
        obs.set(mrpt::obs::IMU_YAW_VEL, imu->gyro_z);
        archive << obs;
      } else if (const auto* s = std::get_if<loc::LaserScan>(&e)) {
        mrpt::obs::CObservation2DRangeScan obs = toMrpt(*s);
        obs.timestamp = mrpt::Clock::fromDouble(s->t);
        obs.sensorLabel = "LIDAR";
        archive << obs;
      }
    }
    flush();
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throwInputError(path, 0, "cannot rename temporary rawlog: " + ec.message());
}

}  // namespace uwbloc::data
