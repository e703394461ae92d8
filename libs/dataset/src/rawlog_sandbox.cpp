// readRawlog: MRPT's deserialiser in a child process. Some corrupt streams make MRPT dereference
// a null pointer (a nested object of the wrong class read into a typed pointer, found by
// fuzzing); a crash there must not take the caller with it. The child reads the rawlog with
// readRawlogInProcess, under an address-space limit of the memory budget, and sends the
// Recording back through a pipe; where it was (object, byte) is kept in a shared page, so that a
// crash is reported at its object.
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <string>
#include <type_traits>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/memory_limits.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/text_io.hpp"

#if defined(__SANITIZE_ADDRESS__)
#define UWBLOC_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UWBLOC_ASAN 1
#endif
#endif

namespace uwbloc::data {

namespace {

// The Recording as bytes: fixed-size fields as they are in memory (the two processes are one
// binary), vectors and strings with their length first.
class Writer {
 public:
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  template <class T>
  void putVector(const std::vector<T>& v) {
    put<uint64_t>(v.size());
    if (!v.empty()) bytes.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  template <int N>
  void putEigen(const Eigen::Matrix<double, N, 1>& v) {
    bytes.append(reinterpret_cast<const char*>(v.data()), sizeof(double) * N);
  }
  void putString(const std::string& s) {
    put<uint64_t>(s.size());
    bytes += s;
  }
  std::string bytes;
};

class Reader {
 public:
  /// Reads `bytes` from offset `at` (the answer's records follow its one-letter tag).
  Reader(const std::string& bytes, size_t at) : bytes_(bytes), at_(at) {}
  template <class T>
  T get() {
    T v;
    take(&v, sizeof v);
    return v;
  }
  template <class T>
  std::vector<T> getVector() {
    std::vector<T> v(count(sizeof(T)));
    take(v.data(), v.size() * sizeof(T));
    return v;
  }
  template <int N>
  Eigen::Matrix<double, N, 1> getEigen() {
    Eigen::Matrix<double, N, 1> v;
    take(v.data(), sizeof(double) * N);
    return v;
  }
  std::string getString() {
    std::string s(count(1), '\0');
    take(s.data(), s.size());
    return s;
  }

 private:
  size_t count(size_t unit) {
    const auto n = get<uint64_t>();
    if (n > (bytes_.size() - at_) / unit) throw std::runtime_error("short record");
    return static_cast<size_t>(n);
  }
  void take(void* out, size_t n) {
    if (n == 0) return;  // an empty vector's data() may be null
    if (n > bytes_.size() - at_) throw std::runtime_error("short record");
    std::memcpy(out, bytes_.data() + at_, n);
    at_ += n;
  }
  const std::string& bytes_;
  size_t at_;
};

template <class Opt>
void putOptional(Writer& w, const Opt& o) {
  w.put<uint8_t>(o ? 1 : 0);
  w.put<double>(o.value_or(0.0));
}

std::optional<double> getOptional(Reader& r) {
  const bool has = r.get<uint8_t>() != 0;
  const double v = r.get<double>();
  return has ? std::optional<double>(v) : std::nullopt;
}

// The answer 'R' and the recording's records.
std::string encode(const Recording& rec) {
  Writer w;
  w.bytes.push_back('R');
  w.putVector(rec.step_times);
  w.put<uint64_t>(rec.counts.size());
  for (const auto& [key, n] : rec.counts) {
    w.putString(key);
    w.put(n);
  }
  w.put<uint64_t>(rec.events.size());
  for (const auto& e : rec.events) {
    w.put<uint8_t>(static_cast<uint8_t>(e.index()));
    if (const auto* r = std::get_if<uwb::Range>(&e)) {
      w.put(r->t);
      w.put(r->anchor_id);
      w.put(r->tag_id);
      w.put(r->range);
      w.putEigen(r->tag_on_robot);
      putOptional(w, r->rx_power_dbm);
      putOptional(w, r->fp_power_dbm);
    } else if (const auto* o = std::get_if<loc::OdometryIncrement>(&e)) {
      w.put(o->t);
      w.putEigen(o->delta);
    } else if (const auto* s = std::get_if<loc::LaserScan>(&e)) {
      w.put(s->t);
      w.putEigen(s->sensor_pose);
      w.put(s->sensor_height);
      w.put(s->angle_min);
      w.put(s->angle_increment);
      w.put(s->max_range);
      w.putVector(s->ranges);
      w.putVector(s->valid);
    } else if (const auto* imu = std::get_if<loc::ImuSample>(&e)) {
      w.put(imu->t);
      w.putEigen(imu->accel);
      w.put(imu->gyro_z);
    }
  }
  return w.bytes;
}

Recording decode(const std::string& bytes, size_t at) {
  Reader r(bytes, at);
  Recording rec;
  rec.step_times = r.getVector<double>();
  for (auto n = r.get<uint64_t>(); n > 0; --n) {
    const std::string key = r.getString();
    rec.counts[key] = r.get<long>();
  }
  const auto events = r.get<uint64_t>();
  rec.events.reserve(static_cast<size_t>(std::min<uint64_t>(events, bytes.size())));
  for (uint64_t i = 0; i < events; ++i) {
    switch (r.get<uint8_t>()) {
      case 0: {
        uwb::Range range;
        range.t = r.get<double>();
        range.anchor_id = r.get<int>();
        range.tag_id = r.get<int>();
        range.on_robot = range.tag_id == 0;
        range.range = r.get<double>();
        range.tag_on_robot = r.getEigen<3>();
        range.rx_power_dbm = getOptional(r);
        range.fp_power_dbm = getOptional(r);
        rec.events.emplace_back(range);
        break;
      }
      case 1: {
        loc::OdometryIncrement o;
        o.t = r.get<double>();
        o.delta = r.getEigen<3>();
        rec.events.emplace_back(o);
        break;
      }
      case 2: {
        loc::LaserScan s;
        s.t = r.get<double>();
        s.sensor_pose = r.getEigen<3>();
        s.sensor_height = r.get<double>();
        s.angle_min = r.get<float>();
        s.angle_increment = r.get<float>();
        s.max_range = r.get<float>();
        s.ranges = r.getVector<float>();
        s.valid = r.getVector<unsigned char>();
        rec.events.emplace_back(std::move(s));
        break;
      }
      case 3: {
        loc::ImuSample imu;
        imu.t = r.get<double>();
        imu.accel = r.getEigen<2>();
        imu.gyro_z = r.get<double>();
        rec.events.emplace_back(imu);
        break;
      }
      default:
        throw std::runtime_error("unknown event kind");
    }
  }
  return rec;
}

bool writeAll(int fd, const std::string& bytes) {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<size_t>(n);
  }
  return true;
}

// The child: read, answer 'R' + the recording or 'E' + the message, and leave without running
// the parent's exit handlers.
[[noreturn]] void child(const std::string& path, int fd, RawlogProgress* progress) {
  // A crash is reported by the parent; the child's own handlers (a sanitizer's, a fuzzer's)
  // would treat it as theirs.
  for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) ::signal(sig, SIG_DFL);
#ifndef UWBLOC_ASAN
  // The memory budget as an address-space limit above what the process already maps (a
  // sanitizer reserves terabytes of address space, so it is left out there).
  std::ifstream statm("/proc/self/statm");
  unsigned long pages = 0;
  if (statm >> pages) {
    const rlim_t limit = static_cast<rlim_t>(pages) * static_cast<rlim_t>(sysconf(_SC_PAGESIZE)) +
                         static_cast<rlim_t>(memoryBudget());
    const rlimit rl{limit, limit};
    ::setrlimit(RLIMIT_AS, &rl);
  }
#endif
  std::string answer;
  int code = 0;
  try {
    answer = encode(readRawlogInProcess(path, progress));
  } catch (const std::exception& e) {
    answer = std::string("E") + e.what();
    code = 1;
  }
  _exit(writeAll(fd, answer) ? code : 2);
}

}  // namespace

Recording readRawlog(const std::string& path) {
  requireRegularFile(path);
  void* shared = ::mmap(nullptr, sizeof(RawlogProgress), PROT_READ | PROT_WRITE,
                        MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (shared == MAP_FAILED) return readRawlogInProcess(path);  // no sandbox: read here
  auto* progress = new (shared) RawlogProgress();
  int fds[2];
  if (::pipe(fds) != 0) {
    ::munmap(shared, sizeof(RawlogProgress));
    return readRawlogInProcess(path);
  }
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    child(path, fds[1], progress);
  }
  ::close(fds[1]);
  std::string answer;
  if (pid > 0) {
    char buffer[1 << 16];
    for (;;) {
      const ssize_t n = ::read(fds[0], buffer, sizeof buffer);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      answer.append(buffer, static_cast<size_t>(n));
    }
  }
  ::close(fds[0]);
  int status = 0;
  if (pid > 0)
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
  const RawlogProgress where = *progress;
  ::munmap(shared, sizeof(RawlogProgress));
  if (pid < 0) return readRawlogInProcess(path);  // fork refused: read here
  if (!answer.empty() && answer[0] == 'E') throw InputError(answer.substr(1));
  if (!answer.empty() && answer[0] == 'R' && WIFEXITED(status) && WEXITSTATUS(status) == 0) {
    try {
      return decode(answer, 1);
    } catch (const std::exception& e) {
      throwInputError(path, 0, std::string("rawlog reader's answer is damaged: ") + e.what());
    }
  }
  const std::string how =
      WIFSIGNALED(status)
          ? "crashed (signal " + std::to_string(WTERMSIG(status)) + ", " +
                strsignal(WTERMSIG(status)) + ")"
          : "stopped without an answer (exit code " + std::to_string(WEXITSTATUS(status)) + ")";
  throwInputError(path, 0,
                  "corrupt rawlog: MRPT's deserialiser " + how + " on object " +
                      std::to_string(where.objects + 1) + " (at byte " +
                      std::to_string(where.position) + " of the uncompressed stream)");
}

}  // namespace uwbloc::data
