#include "uwbloc/evaluation/report.hpp"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>

#include "json_numbers.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/evaluation/bounds.hpp"
#include "uwbloc/evaluation/html_report.hpp"
#include "uwbloc/evaluation/nlos_score.hpp"
#include "uwbloc/evaluation/plots.hpp"
#include "uwbloc/evaluation/trajectory_eval.hpp"

namespace fs = std::filesystem;

namespace uwbloc::eval {

namespace {

long totalRejected(const MethodSummary& m) {
  long n = 0;
  for (const auto& [reason, count] : m.rejected) n += count;
  return n;
}

nlohmann::json number(double v) { return jsonNumber(v); }

}  // namespace

DatasetBounds computeBounds(const data::Dataset& dataset) {
  DatasetBounds b;
  if (!dataset.manifest.bounds || dataset.ground_truth.size() < 2) return b;
  const auto& spec = *dataset.manifest.bounds;
  b.static_rmse = std::sqrt(staticCrlbSeries(dataset, spec.range_sigma).mean());
  b.posterior_rmse = std::sqrt(posteriorCrlb(dataset, spec).mean(5.0));
  b.motion = spec.motion;
  return b;
}

std::string formatTrajectoryTum(const std::vector<loc::PoseEstimate>& trajectory) {
  std::vector<data::TimedPose> poses;
  poses.reserve(trajectory.size());
  // A pose whose heading the method does not observe is written with the identity quaternion
  // (yaw 0), which `evaluate` reads as "no heading" when a whole file has it.
  for (const auto& p : trajectory)
    poses.push_back({p.t, {p.pose.x(), p.pose.y(), p.heading_valid ? p.pose.z() : 0.0}});
  return data::formatTum(poses);
}

std::string fileLabel(const std::string& spec) {
  std::string out;
  for (char c : spec) {
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.' || c == '+')
      out += c;
    else if (c == '=')
      out += '-';
    else
      out += '_';
  }
  return out;
}

namespace {

nlohmann::json metricsJson(const data::Dataset& dataset, const std::vector<MethodSummary>& methods,
                           const DatasetBounds& bounds,
                           const std::optional<Association>& association = std::nullopt) {
  nlohmann::json j;
  j["dataset"] = dataset.name;
  j["pairing"] = describePairing(
      dataset.ground_truth, association.value_or(Association{true, dataset.manifest.gt_max_gap}));
  j["duration_s"] = number(dataset.duration());
  j["events"] = dataset.events.size();
  j["ground_truth_poses"] = dataset.ground_truth.size();
  j["warnings"] = dataset.warnings;
  j["crlb_rmse"] = number(bounds.static_rmse);
  j["pcrb_rmse"] = number(bounds.posterior_rmse);
  j["pcrb_motion"] = bounds.motion;
  j["methods"] = nlohmann::json::array();
  for (const auto& m : methods) {
    nlohmann::json e;
    e["name"] = m.spec;
    e["method"] = m.name;
    e["runs"] = m.runs;
    e["steps"] = m.metrics.steps;
    e["coverage"] = number(m.metrics.coverage);
    const std::string flag = resultFlag(dataset, m);
    e["flag"] = flag.empty() ? nlohmann::json(nullptr) : nlohmann::json(flag);
    e["rmse_x"] = number(m.metrics.rmse_x);
    e["rmse_y"] = number(m.metrics.rmse_y);
    e["rmse_2d"] = number(m.metrics.rmse_2d);
    e["rmse_2d_std"] = number(m.rmse_2d_std);
    e["rmse_2d_worst"] = number(m.worstRmse());
    e["seed_runs"] = nlohmann::json::array();
    for (const auto& r : m.seed_runs)
      e["seed_runs"].push_back({{"seed", r.seed},
                                {"rmse_2d", number(r.rmse_2d)},
                                {"coverage", number(r.coverage)},
                                {"max_2d", number(r.max_2d)}});
    e["mae_2d"] = number(m.metrics.mae_2d);
    e["median_2d"] = number(m.metrics.median_2d);
    e["p95_2d"] = number(m.metrics.p95_2d);
    e["max_2d"] = number(m.metrics.max_2d);
    e["final_2d"] = number(m.metrics.final_2d);
    e["rmse_yaw_deg"] = number(m.metrics.rmse_yaw_deg);
    e["median_yaw_deg"] = number(m.metrics.median_yaw_deg);
    e["p95_yaw_deg"] = number(m.metrics.p95_yaw_deg);
    e["rmse_2d_aligned"] = number(m.metrics.rmse_2d_aligned);
    e["alignment"] = m.metrics.alignment;
    e["rpe_delta"] = m.metrics.rpe_delta;
    e["rpe_trans_rmse"] = number(m.metrics.rpe_trans_rmse);
    e["rpe_rot_rmse_deg"] = number(m.metrics.rpe_rot_rmse_deg);
    e["ms_per_step"] = number(m.ms_per_step);
    e["realtime_factor"] = number(m.realtime_factor);
    e["efficiency_crlb"] = number(m.metrics.rmse_2d / bounds.static_rmse);
    e["efficiency_pcrb"] = number(m.metrics.rmse_2d / bounds.posterior_rmse);
    e["rejected"] = nlohmann::json::object();
    for (const auto& [reason, count] : m.rejected) e["rejected"][reason] = count;
    e["rejected_by_anchor"] = nlohmann::json::object();
    for (const auto& [anchor, reasons] : m.rejected_by_anchor)
      for (const auto& [reason, count] : reasons)
        e["rejected_by_anchor"][std::to_string(anchor)][reason] = count;
    e["accepted_ranges"] = m.accepted_ranges;
    e["resets"] = m.resets;
    e["events"] = nlohmann::json::object();
    for (const auto& [name, count] : m.events) e["events"][name] = count;
    if (!m.estimated_noise.empty() || m.estimated_range_sigma || m.estimated_accel_psd ||
        m.estimated_motion_scale) {
      e["estimated_noise"] = nlohmann::json::object();
      for (const auto& [anchor, n] : m.estimated_noise)
        e["estimated_noise"][std::to_string(anchor)] = {
            {"bias", number(n.bias)}, {"sigma", number(n.sigma)}, {"ranges", n.ranges}};
      if (m.estimated_range_sigma) e["estimated_range_sigma"] = number(*m.estimated_range_sigma);
      for (const auto& [tag, n] : m.estimated_tag_noise)
        e["estimated_tag_sigma"][std::to_string(tag)] = {{"sigma", number(n.sigma)},
                                                         {"ranges", n.ranges}};
      if (m.estimated_range_scale) e["estimated_range_scale"] = number(*m.estimated_range_scale);
      if (const auto& x = m.estimated_range_mixture)
        e["estimated_range_mixture"] = {{"nlos_fraction", number(x->nlos_fraction)},
                                        {"sigma", number(x->sigma)},
                                        {"nlos_mean", number(x->nlos_mean)},
                                        {"weight", number(x->weight)}};
      if (m.estimated_nlos_memory && m.estimated_range_mixture)
        e["estimated_range_mixture"]["nlos_memory"] = number(*m.estimated_nlos_memory);
      if (m.estimated_accel_psd) e["estimated_accel_psd"] = number(*m.estimated_accel_psd);
      if (m.estimated_motion_scale) e["estimated_motion_scale"] = number(*m.estimated_motion_scale);
    }
    e["associated"] = m.metrics.associated;
    e["cdf"] = nlohmann::json::array();
    for (const auto& [err, frac] : m.metrics.cdf) e["cdf"].push_back({number(err), frac});
    if (!m.range_decisions.empty() && !dataset.ground_truth.empty()) {
      const auto sc = scoreNlos(dataset, m.range_decisions);
      for (auto [key, d] : {std::pair{"pose", &sc.pose}, std::pair{"raycast", &sc.raycast},
                            std::pair{"state", &sc.state}}) {
        if (d == &sc.state && sc.state.bad + sc.state.good == 0) continue;
        e["nlos_detection"][key] = {{"bad", d->bad},
                                    {"good", d->good},
                                    {"recall", number(d->recall())},
                                    {"false_alarm", number(d->false_alarm())}};
      }
    }
    e["parameters"] = nlohmann::json::object();
    for (const auto& p : m.parameters) e["parameters"][p.key] = p.value;
    j["methods"].push_back(e);
  }
  return j;
}

}  // namespace

std::string formatMetricsJson(const data::Dataset& dataset,
                              const std::vector<MethodSummary>& methods,
                              const DatasetBounds& bounds) {
  return metricsJson(dataset, methods, bounds).dump(2) + "\n";
}

std::string formatMetricsCsv(const data::Dataset& dataset,
                             const std::vector<MethodSummary>& methods) {
  std::ostringstream out;
  out << "dataset,method,runs,steps,coverage,rmse_x,rmse_y,rmse_2d,rmse_2d_std,mae_2d,"
         "median_2d,p95_2d,max_2d,rmse_yaw_deg,ms_per_step,realtime_factor,rejected_total,resets,"
         "rmse_2d_aligned,rpe_trans_rmse,rpe_rot_rmse_deg\n";
  // A metric that cannot be computed is an empty field, never "nan".
  auto v = [](double x) {
    std::ostringstream s;
    if (std::isfinite(x)) s << x;
    return s.str();
  };
  for (const auto& m : methods) {
    out << dataset.name << ",\"" << m.spec << "\"," << m.runs << "," << m.metrics.steps << ","
        << v(m.metrics.coverage) << "," << v(m.metrics.rmse_x) << "," << v(m.metrics.rmse_y) << ","
        << v(m.metrics.rmse_2d) << "," << v(m.rmse_2d_std) << "," << v(m.metrics.mae_2d) << ","
        << v(m.metrics.median_2d) << "," << v(m.metrics.p95_2d) << "," << v(m.metrics.max_2d) << ","
        << v(m.metrics.rmse_yaw_deg) << "," << v(m.ms_per_step) << "," << v(m.realtime_factor)
        << "," << totalRejected(m) << "," << m.resets << "," << v(m.metrics.rmse_2d_aligned) << ","
        << v(m.metrics.rpe_trans_rmse) << "," << v(m.metrics.rpe_rot_rmse_deg) << "\n";
  }
  return out.str();
}

namespace {

using Json = nlohmann::json;

double num(const Json& j, const char* key) { return jsonNum(j, key); }

// A metrics.json object keyed by anchor id, in numeric order (JSON keeps keys as text).
std::vector<std::pair<int, const Json*>> byAnchor(const Json& object) {
  std::vector<std::pair<int, const Json*>> out;
  for (auto it = object.begin(); it != object.end(); ++it)
    out.emplace_back(std::stoi(it.key()), &it.value());
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

std::string cell(double v, int width, int precision) {
  char text[32];
  if (std::isfinite(v))
    std::snprintf(text, sizeof text, "%*.*f", width, precision, v);
  else
    std::snprintf(text, sizeof text, "%*s", width, "-");  // undefined: no estimate to score
  return text;
}

long totalRejected(const Json& m) {
  long n = 0;
  for (const auto& count : m.value("rejected", Json::object())) n += count.get<long>();
  return n;
}

// One row per method.
void tableRows(std::ostringstream& out, const Json& methods) {
  for (const auto& m : methods) {
    out << std::left << std::setw(22) << m["name"].get<std::string>() << std::right << " "
        << std::setw(4) << m["runs"].get<int>() << " " << std::setw(6) << m["steps"].get<long>()
        << " " << cell(num(m, "coverage"), 5, 2) << " " << cell(num(m, "rmse_x"), 7, 3) << " "
        << cell(num(m, "rmse_y"), 7, 3) << " " << cell(num(m, "rmse_2d"), 7, 3) << " "
        << cell(num(m, "rmse_2d_std"), 6, 3) << " " << cell(num(m, "rmse_2d_worst"), 7, 3) << " "
        << cell(num(m, "mae_2d"), 7, 3) << " " << cell(num(m, "median_2d"), 7, 3) << " "
        << cell(num(m, "p95_2d"), 7, 3) << " " << cell(num(m, "max_2d"), 7, 3) << " "
        << cell(num(m, "rmse_2d_aligned"), 7, 3) << " " << cell(num(m, "rpe_trans_rmse"), 7, 3)
        << " " << cell(num(m, "rmse_yaw_deg"), 7, 2) << " " << cell(num(m, "ms_per_step"), 9, 4)
        << " " << cell(num(m, "realtime_factor"), 8, 0) << " " << std::setw(7) << totalRejected(m)
        << "\n";
  }
}

// Efficiency against the Cramér-Rao bounds, and the NLOS detectors' scores.
void boundsAndNlosLines(std::ostringstream& out, const Json& j) {
  char buf[512];
  const double crlb = num(j, "crlb_rmse"), pcrb = num(j, "pcrb_rmse");
  if (std::isfinite(crlb)) {
    std::snprintf(buf, sizeof buf,
                  "Bounds: sqrt(mean static CRLB) %.4f m, sqrt(mean posterior CRLB, %s motion) "
                  "%.4f m. Efficiency = rmse_2d / bound:\n",
                  crlb, j.value("pcrb_motion", std::string()).c_str(), pcrb);
    out << buf;
    for (const auto& m : j["methods"]) {
      std::snprintf(buf, sizeof buf, "  %-22s vs CRLB %6.2f   vs PCRB %6.2f\n",
                    m["name"].get<std::string>().c_str(), num(m, "rmse_2d") / crlb,
                    num(m, "rmse_2d") / pcrb);
      out << buf;
    }
  }
  for (const auto& m : j["methods"]) {
    if (!m.contains("nlos_detection")) continue;
    const Json& pose = m["nlos_detection"]["pose"];
    const Json& ray = m["nlos_detection"]["raycast"];
    std::snprintf(buf, sizeof buf,
                  "  %s NLOS detection (range error > 0.5 m vs ground truth: %ld bad, %ld good): "
                  "LiDAR-pose test recall %.3f, false alarm %.3f; map ray-cast recall %.3f, "
                  "false alarm %.3f\n",
                  m["name"].get<std::string>().c_str(), pose["bad"].get<long>(),
                  pose["good"].get<long>(), num(pose, "recall"), num(pose, "false_alarm"),
                  num(ray, "recall"), num(ray, "false_alarm"));
    out << buf;
    if (m["nlos_detection"].contains("state")) {
      const Json& state = m["nlos_detection"]["state"];
      std::snprintf(buf, sizeof buf,
                    "    each link's tracked NLOS state (P(NLOS) > 0.5): recall %.3f, false alarm "
                    "%.3f\n",
                    num(state, "recall"), num(state, "false_alarm"));
      out << buf;
    }
  }
}

// Rejections by reason and anchor, and other events, per method.
void rejectionLines(std::ostringstream& out, const Json& methods) {
  for (const auto& m : methods) {
    if (m["rejected"].empty()) continue;
    out << "  " << m["name"].get<std::string>() << " rejected:";
    for (const auto& [reason, count] : m["rejected"].items())
      out << " " << reason << "=" << count.get<long>();
    if (!m["rejected_by_anchor"].empty()) {
      out << "  | by anchor:";
      for (const auto& [anchor, reasons] : byAnchor(m["rejected_by_anchor"])) {
        out << " " << anchor << "{";
        bool first = true;
        for (const auto& [reason, count] : reasons->items()) {
          out << (first ? "" : ",") << reason << "=" << count.get<long>();
          first = false;
        }
        out << "}";
      }
    }
    out << "\n";
  }
  for (const auto& m : methods) {
    if (!m.contains("estimated_noise")) continue;
    out << "  " << m["name"].get<std::string>() << " estimated noise:";
    char buf[192];
    if (m.contains("estimated_range_sigma")) {
      std::snprintf(buf, sizeof buf, " model sigma %.3f m;", num(m, "estimated_range_sigma"));
      out << buf;
    }
    if (m.contains("estimated_tag_sigma")) {
      out << " per tag";
      for (const auto& [tag, x] : m["estimated_tag_sigma"].items()) {
        std::snprintf(buf, sizeof buf, " %s{sigma %.3f, n %ld}", tag.c_str(), num(x, "sigma"),
                      x["ranges"].get<long>());
        out << buf;
      }
      out << ";";
    }
    if (m.contains("estimated_range_scale")) {
      std::snprintf(buf, sizeof buf, " range scale %+.4f (ranges read %.2f %% %s);",
                    num(m, "estimated_range_scale"),
                    100.0 * std::abs(num(m, "estimated_range_scale")),
                    num(m, "estimated_range_scale") >= 0 ? "long" : "short");
      out << buf;
    }
    if (m.contains("estimated_range_mixture")) {
      const auto& x = m["estimated_range_mixture"];
      std::snprintf(buf, sizeof buf,
                    " range likelihood: %.0f %% NLOS (+%.3f m mean), LOS std %.3f m, each range "
                    "counted %.3g (errors correlated over %.3g ranges);",
                    100.0 * num(x, "nlos_fraction"), num(x, "nlos_mean"), num(x, "sigma"),
                    x.contains("weight") ? num(x, "weight") : 1.0,
                    x.contains("weight") ? 1.0 / num(x, "weight") : 1.0);
      out << buf;
      if (x.contains("nlos_memory")) {
        std::snprintf(buf, sizeof buf, " each link's NLOS state over %.3g s;",
                      num(x, "nlos_memory"));
        out << buf;
      }
    }
    if (m.contains("estimated_accel_psd")) {
      std::snprintf(buf, sizeof buf, " motion q %.3g m^2/s^3;", num(m, "estimated_accel_psd"));
      out << buf;
    }
    if (m.contains("estimated_motion_scale")) {
      std::snprintf(buf, sizeof buf, " odometry noise x%.4g;", num(m, "estimated_motion_scale"));
      out << buf;
    }
    for (const auto& [anchor, n] : byAnchor(m["estimated_noise"])) {
      std::snprintf(buf, sizeof buf, " %d{bias %+.3f, sigma %.3f, n %ld}", anchor, num(*n, "bias"),
                    num(*n, "sigma"), (*n)["ranges"].get<long>());
      out << buf;
    }
    out << "\n";
  }
  for (const auto& m : methods) {
    if (m["events"].empty()) continue;
    out << "  " << m["name"].get<std::string>() << " events:";
    for (const auto& [name, count] : m["events"].items())
      out << " " << name << "=" << count.get<long>();
    out << "\n";
  }
}

std::string tableFromJson(const Json& j) {
  std::ostringstream out;
  char buf[512];
  std::snprintf(buf, sizeof buf, "Dataset %s: %.1f s, %ld events, %ld ground-truth poses\n",
                j["dataset"].get<std::string>().c_str(), num(j, "duration_s"),
                j.value("events", 0L), j.value("ground_truth_poses", 0L));
  out << buf;
  for (const auto& w : j.value("warnings", Json::array()))
    out << "WARNING: " << w.get<std::string>() << "\n";
  std::snprintf(buf, sizeof buf,
                "%-22s %4s %6s %5s %7s %7s %7s %6s %7s %7s %7s %7s %7s %7s %7s %7s %9s %8s %7s\n",
                "method", "runs", "steps", "cov", "rmse_x", "rmse_y", "rmse_2d", "±std", "worst",
                "mae", "median", "p95", "max", "aligned", "rpe_1m", "yaw_deg", "ms/step", "xRT",
                "reject");
  out << buf;
  tableRows(out, j["methods"]);
  for (const auto& m : j["methods"]) {
    const std::string name = m["name"].get<std::string>();
    const std::string flag = m["flag"].is_string() ? m["flag"].get<std::string>() : "";
    if (flag == "no_estimate")
      out << "FLAGGED: " << name << " produced no estimate that can be scored\n";
    else if (flag == "low_coverage")
      out << "FLAGGED: " << name << " covers only " << std::lround(100 * num(m, "coverage"))
          << " % of the ground truth (under 50 %)\n";
    // An NLOS model that could not judge a range did nothing to it: say so, not only count it.
    if (const auto it = m["events"].find("nlos_no_powers"); it != m["events"].end())
      out << "WARNING: " << name << ": its NLOS model judged none of " << it->get<long>()
          << " ranges, which carry no received and first-path power (a range_features side "
             "file gives them)\n";
  }
  out << "Errors in metres " << j.value("pairing", std::string("against interpolated ground truth"))
      << "; cov = fraction of ground-truth samples with an estimate within 1 s; worst = the worst "
         "seed's rmse_2d; xRT = "
         "real-time factor; yaw_deg = heading RMSE [deg] (- when the reference has no heading); "
         "aligned = rmse_2d after the best rigid SE(2) alignment; rpe_1m = RMSE of the relative "
         "pose error's translation over 1 m stretches of the reference path.\n";
  // A shared learning start is solved once: the time is in the first method's ms/step only.
  std::string reused;
  for (const auto& m : j["methods"])
    if (m["events"].contains("range_model_reused"))
      reused += (reused.empty() ? "" : ", ") + m["name"].get<std::string>();
  if (!reused.empty())
    out << "ms/step and xRT may leave out the learning start that these methods shared with "
           "another (solved once; compare --own-learning times each its own): "
        << reused << "\n";
  boundsAndNlosLines(out, j);
  rejectionLines(out, j["methods"]);
  return out.str();
}

}  // namespace

std::string formatTable(const data::Dataset& dataset, const std::vector<MethodSummary>& methods,
                        const DatasetBounds& bounds,
                        const std::optional<Association>& association) {
  return tableFromJson(metricsJson(dataset, methods, bounds, association));
}

std::string formatTableFromJson(const std::string& metrics_json) {
  return tableFromJson(Json::parse(metrics_json));
}

namespace {

// Replaces `target` by `fresh`: an atomic exchange of the two directories when `target` exists
// (Linux renameat2 RENAME_EXCHANGE), then the old one is removed; a rename otherwise.
void replaceDirectory(const fs::path& fresh, const fs::path& target) {
  std::error_code ec;
  if (fs::exists(target, ec)) {
    if (::renameat2(AT_FDCWD, fresh.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE) != 0)
      throw data::InputError(target.string() +
                             ": cannot replace the run directory: " + std::strerror(errno));
    fs::remove_all(fresh, ec);  // now the previous run
    return;
  }
  fs::rename(fresh, target, ec);
  if (ec)
    throw data::InputError(target.string() + ": cannot create the run directory: " + ec.message());
}

bool processAlive(long pid) {
  return pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM);
}

}  // namespace

RunDirectoryLock::RunDirectoryLock(const std::string& out_dir) {
  const fs::path dir = fs::path(out_dir).lexically_normal();
  if (dir.filename().empty()) throw data::InputError(out_dir + ": not a directory name");
  std::error_code ec;
  if (!dir.parent_path().empty()) fs::create_directories(dir.parent_path(), ec);
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw data::InputError(out_dir + ": exists and is not a directory");
  path_ = dir.string() + ".lock";
  for (int attempt = 0; attempt < 2; ++attempt) {
    const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
    if (fd >= 0) {
      const std::string pid = std::to_string(::getpid()) + "\n";
      const bool ok = ::write(fd, pid.data(), pid.size()) == static_cast<ssize_t>(pid.size());
      ::close(fd);
      if (!ok) break;
      return;
    }
    if (errno != EEXIST)
      throw data::InputError(path_ + ": cannot create the lock (is " + dir.parent_path().string() +
                             " writable?): " + std::strerror(errno));
    long holder = 0;
    std::ifstream(path_) >> holder;
    if (processAlive(holder))
      throw data::InputError(out_dir + ": another run (process " + std::to_string(holder) +
                             ") is writing this run directory; lock file " + path_);
    fs::remove(path_, ec);  // a stale lock: its process is gone
  }
  throw data::InputError(path_ + ": cannot take the lock");
}

RunDirectoryLock::~RunDirectoryLock() {
  std::error_code ec;
  if (!path_.empty()) fs::remove(path_, ec);
}

void writeRunDirectory(const std::string& out_dir, const data::Dataset& dataset,
                       const std::vector<MethodSummary>& methods, const RunInfo& info) {
  const fs::path target = fs::path(out_dir).lexically_normal();
  const fs::path fresh = target.string() + data::uniqueSuffix();
  data::ensureDirectory(fresh.string());
  try {
    writeRunFiles(fresh.string(), dataset, methods, info);
    replaceDirectory(fresh, target);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(fresh, ec);
    throw;
  }
}

void writeRunFiles(const std::string& out_dir, const data::Dataset& dataset,
                   const std::vector<MethodSummary>& methods, const RunInfo& info) {
  const fs::path dir(out_dir);
  for (const auto& m : methods) {
    data::writeFileAtomic((dir / (fileLabel(m.spec) + ".tum")).string(),
                          formatTrajectoryTum(m.trajectory));
    for (const auto& [suffix, contents] : m.artifacts)
      data::writeFileAtomic((dir / (fileLabel(m.spec) + "_" + suffix)).string(), contents);
  }
  Json j = metricsJson(dataset, methods, info.bounds, info.association);
  j["wall_time_s"] = number(info.wall_seconds);
  j["jobs"] = info.jobs;
  data::writeFileAtomic((dir / "metrics.json").string(), j.dump(2) + "\n");
  data::writeFileAtomic((dir / "metrics.csv").string(), formatMetricsCsv(dataset, methods));
  const std::string table = tableFromJson(j);
  data::writeFileAtomic((dir / "report.txt").string(), table);
  std::vector<PlotFile> plots;
  if (info.plots) plots = writePlots((dir / "plots").string(), dataset, methods, info.jobs);
  data::writeFileAtomic((dir / "report.html").string(),
                        formatHtmlReport(dataset, methods, table, plots, (dir / "plots").string(),
                                         kChartJsPath, info.jobs));
  for (const auto& [name, contents] : info.extra_files)
    data::writeFileAtomic((dir / name).string(), contents);

  std::ostringstream cfg;
  cfg << "# Effective configuration of this run\n[run]\n"
      << "dataset = " << info.dataset_manifest << "\n"
      << "data_dir = " << info.data_dir << "\n"
      << "seed = " << info.seed << "\n"
      << "repeat = " << info.repeat << "\n";
  cfg << "\n[dataset]\nname = " << dataset.name << "\nrawlog = " << dataset.manifest.rawlog
      << "\nground_truth = " << dataset.manifest.ground_truth
      << "\nground_truth_format = " << data::toString(dataset.manifest.ground_truth_format) << "\n";
  cfg << "\n[anchors]\n";
  for (const auto& a : dataset.anchors)
    cfg << "# anchor " << a.id << " (map frame): " << a.position.x() << " " << a.position.y() << " "
        << a.position.z() << "\n";
  for (const auto& m : methods) {
    cfg << "\n[" << m.spec << "]\n";
    for (const auto& p : m.parameters) cfg << p.key << " = " << p.value << "\n";
  }
  data::writeFileAtomic((dir / "config.ini").string(), cfg.str());
}

}  // namespace uwbloc::eval
