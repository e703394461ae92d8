#include "uwbloc/evaluation/html_report.hpp"

#include <mrpt/system/string_utils.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "json_numbers.hpp"
#include "uwbloc/evaluation/metrics.hpp"

namespace fs = std::filesystem;

namespace uwbloc::eval {

namespace {

// MRPT's base-64 (it breaks lines every 72 characters, which URL parsing drops).
std::string base64(const std::string& bytes) {
  std::string out;
  mrpt::system::encodeBase64(std::vector<uint8_t>(bytes.begin(), bytes.end()), out);
  return out;
}

std::string readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string escapeHtml(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// Text placed inside <script>: a "</" would end the element early.
std::string scriptSafe(std::string s) {
  for (size_t p = 0; (p = s.find("</", p)) != std::string::npos; p += 3) s.replace(p, 2, "<\\/");
  return s;
}

double mm(double v) { return std::round(v * 1000.0) / 1000.0; }

nlohmann::json number(double v) { return jsonNumber(mm(v)); }

// The charts' data, each series thinned to at most ~3000 points: the reference, the anchors
// and the map (a grey PNG with its extent) here, each method's part in methodChart().
nlohmann::json chartData(const data::Dataset& ds) {
  nlohmann::json j;
  auto thin = [](size_t n) { return std::max<size_t>(1, n / 3000); };
  j["reference"] = nlohmann::json::array();
  for (size_t i = 0, s = thin(ds.ground_truth.size()); i < ds.ground_truth.size(); i += s)
    j["reference"].push_back({mm(ds.ground_truth[i].pose.x()), mm(ds.ground_truth[i].pose.y())});
  j["anchors"] = nlohmann::json::array();
  for (const auto& a : ds.anchors)
    j["anchors"].push_back({{"id", a.id}, {"x", mm(a.position.x())}, {"y", mm(a.position.y())}});
  if (ds.map) {
    const auto& map = *ds.map;
    cv::Mat grey(map.sizeY(), map.sizeX(), CV_8UC1);
    for (int cy = 0; cy < map.sizeY(); ++cy)
      for (int cx = 0; cx < map.sizeX(); ++cx) {
        const float p = map.freeProbability(cx, cy);
        grey.at<uint8_t>(map.sizeY() - 1 - cy, cx) = p > 0.6f ? 255 : p < 0.4f ? 70 : 222;
      }
    std::vector<uchar> png;
    if (cv::imencode(".png", grey, png)) {
      const auto b = map.bounds();
      j["map"] = {{"src", "data:image/png;base64," + base64(std::string(png.begin(), png.end()))},
                  {"xmin", b.xmin},
                  {"xmax", b.xmax},
                  {"ymin", b.ymin},
                  {"ymax", b.ymax}};
    }
  }
  return j;
}

// One method's trajectory, error over time and CDF.
nlohmann::json methodChart(const data::Dataset& ds, const MethodSummary& m) {
  const double t0 = ds.ground_truth.empty() ? ds.start_time : ds.ground_truth.front().t;
  auto thin = [](size_t n) { return std::max<size_t>(1, n / 3000); };
  nlohmann::json e;
  e["name"] = m.spec;
  e["trajectory"] = nlohmann::json::array();
  for (size_t i = 0, s = thin(m.trajectory.size()); i < m.trajectory.size(); i += s)
    if (std::isfinite(m.trajectory[i].pose.x()) && std::isfinite(m.trajectory[i].pose.y()))
      e["trajectory"].push_back({mm(m.trajectory[i].pose.x()), mm(m.trajectory[i].pose.y())});
  const auto errors = associate(m.trajectory, ds.ground_truth, ds.manifest.gt_max_gap);
  e["error"] = nlohmann::json::array();
  std::vector<double> sorted;
  for (size_t i = 0, s = thin(errors.size()); i < errors.size(); ++i) {
    sorted.push_back(errors[i].e2d);
    if (i % s == 0) e["error"].push_back({mm(errors[i].t - t0), mm(errors[i].e2d)});
  }
  std::sort(sorted.begin(), sorted.end());
  e["cdf"] = nlohmann::json::array();
  for (size_t i = 0, s = thin(sorted.size()); i < sorted.size(); i += s)
    e["cdf"].push_back({mm(sorted[i]), mm(static_cast<double>(i + 1) / sorted.size())});
  if (!sorted.empty()) e["cdf"].push_back({mm(sorted.back()), 1.0});
  e["rmse_2d"] = number(m.metrics.rmse_2d);
  return e;
}

// A picture inlined as a data URI, with its caption; empty when the file cannot be read.
std::string figureHtml(const PlotFile& p, const std::string& plots_dir) {
  const std::string png = readAll((fs::path(plots_dir) / p.file).string());
  if (png.empty()) return {};
  return "<figure><img alt=\"" + escapeHtml(p.caption) + "\" src=\"data:image/png;base64," +
         base64(png) + "\"><figcaption>" + escapeHtml(p.caption) + " (plots/" + escapeHtml(p.file) +
         ")</figcaption></figure>\n";
}

// Builds the charts, makes the trajectory zoomable (wheel: zoom about the cursor; drag: pan;
// double-click: reset), then checks that every chart drew points before reporting "ok".
const char* kScript = R"JS(
(function () {
  var statusText = document.getElementById('status');
  function status(s) { document.body.setAttribute('data-report-status', s); statusText.textContent = s; }
  window.addEventListener('error', function (e) { status('error: ' + e.message); });
  var D = JSON.parse(document.getElementById('report-data').textContent);
  if (typeof Chart === 'undefined') { status('static'); return; }
  var palette = ['#0072B2', '#E69F00', '#009E73', '#D55E00', '#CC79A7', '#56B4E9', '#F0E442'];
  var dashes = [[], [8, 5], [2, 4]];
  function style(i) { return { color: palette[i % palette.length], dash: dashes[Math.floor(i / palette.length) % 3] }; }
  function pts(a) { return a.map(function (p) { return { x: p[0], y: p[1] }; }); }
  var common = { animation: false, responsive: true, maintainAspectRatio: true, parsing: false, normalized: true,
                 plugins: { legend: { position: 'right' } } };
  function axes(xt, yt, extra) {
    var s = { x: { type: 'linear', title: { display: true, text: xt } }, y: { type: 'linear', title: { display: true, text: yt } } };
    if (extra) { Object.assign(s.x, extra.x || {}); Object.assign(s.y, extra.y || {}); }
    return s;
  }
  var mapImg = null;
  if (D.map) { mapImg = new Image(); mapImg.src = D.map.src; }
  var mapPlugin = { id: 'mapBackground', beforeDatasetsDraw: function (chart) {
    if (!mapImg || !mapImg.complete || chart.canvas.id !== 'trajectory') return;
    var x = chart.scales.x, y = chart.scales.y, a = chart.chartArea, ctx = chart.ctx;
    ctx.save(); ctx.beginPath(); ctx.rect(a.left, a.top, a.right - a.left, a.bottom - a.top); ctx.clip();
    var l = x.getPixelForValue(D.map.xmin), r = x.getPixelForValue(D.map.xmax);
    var t = y.getPixelForValue(D.map.ymax), b = y.getPixelForValue(D.map.ymin);
    ctx.drawImage(mapImg, l, t, r - l, b - t); ctx.restore(); } };

  // The trajectory chart, one metre as long on both axes.
  var xs = [], ys = [];
  D.reference.forEach(function (p) { xs.push(p[0]); ys.push(p[1]); });
  D.anchors.forEach(function (a) { xs.push(a.x); ys.push(a.y); });
  if (!xs.length) D.methods.forEach(function (m) { m.trajectory.forEach(function (p) { xs.push(p[0]); ys.push(p[1]); }); });
  if (!xs.length) { xs = [-1, 1]; ys = [-1, 1]; }  // nothing to show: the check below says so
  var x0 = Math.min.apply(null, xs), x1 = Math.max.apply(null, xs), y0 = Math.min.apply(null, ys), y1 = Math.max.apply(null, ys);
  var pad = 0.08 * Math.max(x1 - x0, y1 - y0, 1);
  x0 -= pad; x1 += pad; y0 -= pad; y1 += pad;
  var ratio = Math.min(2.4, Math.max(0.6, (x1 - x0) / (y1 - y0)));
  var trajSets = [{ label: 'reference', data: pts(D.reference), showLine: true, pointRadius: 0, borderColor: '#000000', borderWidth: 3 }];
  D.methods.forEach(function (m, i) {
    var s = style(i);
    trajSets.push({ label: m.name, data: pts(m.trajectory), showLine: true, pointRadius: 0, borderWidth: 1.5,
                    borderColor: s.color, backgroundColor: s.color, borderDash: s.dash });
  });
  if (D.anchors.length)
    trajSets.push({ label: 'anchors', data: D.anchors.map(function (a) { return { x: a.x, y: a.y }; }), pointStyle: 'triangle',
                    pointRadius: 8, backgroundColor: '#D55E00', borderColor: '#D55E00' });
  var home = { x0: x0, x1: x1, y0: y0, y1: y1 };
  var traj = new Chart(document.getElementById('trajectory'), { type: 'scatter', data: { datasets: trajSets },
    options: Object.assign({}, common, { aspectRatio: ratio,
      scales: axes('x [m]', 'y [m]', { x: { min: x0, max: x1 }, y: { min: y0, max: y1 } }) }), plugins: [mapPlugin] });
  if (mapImg) mapImg.onload = function () { traj.update('none'); };
  (function zoomable(chart) {
    var c = chart.canvas, drag = null;
    function set(r) { var o = chart.options.scales; o.x.min = r.x0; o.x.max = r.x1; o.y.min = r.y0; o.y.max = r.y1; chart.update('none'); }
    function range() { var s = chart.scales; return { x0: s.x.min, x1: s.x.max, y0: s.y.min, y1: s.y.max }; }
    c.addEventListener('wheel', function (e) {
      e.preventDefault();
      var r = range(), k = e.deltaY < 0 ? 0.8 : 1.25;
      var px = chart.scales.x.getValueForPixel(e.offsetX), py = chart.scales.y.getValueForPixel(e.offsetY);
      set({ x0: px + (r.x0 - px) * k, x1: px + (r.x1 - px) * k, y0: py + (r.y0 - py) * k, y1: py + (r.y1 - py) * k });
    }, { passive: false });
    c.addEventListener('mousedown', function (e) { drag = { x: e.offsetX, y: e.offsetY, r: range() }; });
    window.addEventListener('mouseup', function () { drag = null; });
    c.addEventListener('mousemove', function (e) {
      if (!drag) return;
      var s = chart.scales, dx = (e.offsetX - drag.x) * (drag.r.x1 - drag.r.x0) / (s.x.right - s.x.left);
      var dy = (e.offsetY - drag.y) * (drag.r.y1 - drag.r.y0) / (s.y.bottom - s.y.top);
      set({ x0: drag.r.x0 - dx, x1: drag.r.x1 - dx, y0: drag.r.y0 + dy, y1: drag.r.y1 + dy });
    });
    c.addEventListener('dblclick', function () { set(home); });
  })(traj);

  function lineChart(id, key, xt, yt, extra) {
    var sets = D.methods.map(function (m, i) {
      var s = style(i);
      return { label: m.name, data: pts(m[key]), showLine: true, pointRadius: 0, borderWidth: 1.5,
               borderColor: s.color, backgroundColor: s.color, borderDash: s.dash, stepped: key === 'cdf' };
    });
    return new Chart(document.getElementById(id), { type: 'scatter', data: { datasets: sets },
      options: Object.assign({}, common, { aspectRatio: 2.6, scales: axes(xt, yt, extra) }) });
  }
  var charts = [traj];
  if (D.reference.length) {
    charts.push(lineChart('errors', 'error', 'time since the first reference pose [s]', 'planar error [m]', { y: { min: 0 } }));
    charts.push(lineChart('cdf', 'cdf', 'planar error [m]', 'fraction of estimates <= error', { x: { min: 0 }, y: { min: 0, max: 1 } }));
  }

  // Every chart must have drawn: points in its datasets, and coloured pixels in its plot area
  // (grid lines and text are grey, the palette is not).
  var problems = [];
  charts.forEach(function (chart) {
    var n = 0;
    chart.data.datasets.forEach(function (d, i) { if (chart.isDatasetVisible(i)) n += chart.getDatasetMeta(i).data.length; });
    var a = chart.chartArea, w = Math.floor(a.right - a.left), h = Math.floor(a.bottom - a.top);
    var coloured = 0;
    if (w > 0 && h > 0) {
      var px = chart.ctx.getImageData(Math.ceil(a.left), Math.ceil(a.top), w, h).data;
      for (var k = 0; k < px.length; k += 4) {
        var mx = Math.max(px[k], px[k + 1], px[k + 2]), mn = Math.min(px[k], px[k + 1], px[k + 2]);
        if (px[k + 3] > 128 && mx - mn > 60) coloured++;
      }
    }
    chart.canvas.setAttribute('data-points', n);
    chart.canvas.setAttribute('data-coloured-pixels', coloured);
    if (n === 0 || coloured < 20) problems.push(chart.canvas.id + ' is empty (' + n + ' points, ' + coloured + ' coloured pixels)');
  });
  status(problems.length ? 'error: ' + problems.join('; ') : 'ok');
})();
)JS";

}  // namespace

std::string formatHtmlReport(const data::Dataset& dataset,
                             const std::vector<MethodSummary>& methods, const std::string& table,
                             const std::vector<PlotFile>& plots, const std::string& plots_dir,
                             const std::string& chart_js, int jobs) {
  const std::string library = readAll(chart_js);
  // Inlining each picture (base 64) and each method's chart series are independent: they are
  // made on `jobs` threads, then placed in order.
  // The charts' JSON is the dataset's part with "methods": [...] spliced in, each method's
  // part written as text on its own thread.
  std::vector<std::string> figures(plots.size());
  std::vector<std::string> method_charts(methods.size());
  std::string charts, library_script;
  parallelFor(2 + plots.size() + methods.size(), jobs, [&](size_t k) {
    if (k == 0)
      charts = scriptSafe(chartData(dataset).dump());
    else if (k == 1)
      library_script = scriptSafe(library);
    else if (k < 2 + plots.size())
      figures[k - 2] = figureHtml(plots[k - 2], plots_dir);
    else
      method_charts[k - 2 - plots.size()] =
          scriptSafe(methodChart(dataset, methods[k - 2 - plots.size()]).dump());
  });
  charts.pop_back();  // the closing brace
  charts += charts.size() > 1 ? ",\"methods\":[" : "\"methods\":[";
  for (size_t i = 0; i < method_charts.size(); ++i) charts += (i ? "," : "") + method_charts[i];
  charts += "]}";
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>uwbloc: "
    << escapeHtml(dataset.name) << "</title>\n<style>\n"
    << "body{font-family:sans-serif;margin:1.5em auto;max-width:1250px;color:#111}"
       "table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #bbb;padding:3px 7px;"
       "text-align:right}th{background:#eee}td:first-child,th:first-child{text-align:left}"
       "pre{font-size:11px;overflow-x:auto;background:#f6f6f6;padding:8px}figure{margin:1em 0}"
       "figure img{max-width:100%;border:1px solid #ddd}.flag{color:#D55E00;font-weight:bold}"
       ".note{color:#555}canvas{max-width:100%}\n</style></head>\n"
    << "<body data-report-status=\"loading\">\n<h1>uwbloc run: " << escapeHtml(dataset.name)
    << "</h1>\n";
  char buf[256];
  std::snprintf(buf, sizeof buf, "%.1f s, %zu events, %zu reference poses, %zu anchors",
                dataset.duration(), dataset.events.size(), dataset.ground_truth.size(),
                dataset.anchors.size());
  h << "<p>" << buf << ". Report status: <span id=\"status\">loading</span></p>\n";
  for (const auto& w : dataset.warnings)
    h << "<p class=\"flag\">WARNING: " << escapeHtml(w) << "</p>\n";

  h << "<h2>Results</h2>\n<table><tr><th>method</th><th>runs</th><th>coverage</th>"
       "<th>RMSE 2D [m]</th><th>aligned [m]</th><th>RPE 1 m [m]</th><th>max [m]</th>"
       "<th>yaw RMSE [deg]</th><th>ms/step</th><th>flag</th></tr>\n";
  auto cell = [](double v, const char* fmt) {
    char c[48];
    if (std::isfinite(v))
      std::snprintf(c, sizeof c, fmt, v);
    else
      std::snprintf(c, sizeof c, "-");
    return std::string(c);
  };
  for (const auto& m : methods) {
    const std::string flag = resultFlag(dataset, m);
    h << "<tr><td>" << escapeHtml(m.spec) << "</td><td>" << m.runs << "</td><td>"
      << cell(m.metrics.coverage, "%.2f") << "</td><td>" << cell(m.metrics.rmse_2d, "%.3f")
      << "</td><td>" << cell(m.metrics.rmse_2d_aligned, "%.3f") << "</td><td>"
      << cell(m.metrics.rpe_trans_rmse, "%.3f") << "</td><td>" << cell(m.metrics.max_2d, "%.3f")
      << "</td><td>" << cell(m.metrics.rmse_yaw_deg, "%.2f") << "</td><td>"
      << cell(m.ms_per_step, "%.4f") << "</td><td class=\"flag\">" << escapeHtml(flag)
      << "</td></tr>\n";
  }
  h << "</table>\n";

  h << "<h2>Interactive charts</h2>\n";
  if (library.empty())
    h << "<p class=\"note\">The interactive charts need Chart.js from Debian's libjs-chart.js ("
      << escapeHtml(chart_js) << " was not found when this report was written); the pictures "
      << "below show the same.</p>\n";
  else
    h << "<p class=\"note\">Trajectory: the mouse wheel zooms, dragging pans, a double-click "
         "resets. Click a legend entry to hide a method.</p>\n";
  h << "<canvas id=\"trajectory\"></canvas>\n";
  if (!dataset.ground_truth.empty())
    h << "<canvas id=\"errors\"></canvas>\n<canvas id=\"cdf\"></canvas>\n";

  h << "<h2>Pictures</h2>\n";
  // The pictures make most of the page (megabytes): appended once to a buffer of the final size.
  std::string page = h.str();
  size_t size = page.size() + charts.size() + library_script.size() + table.size() * 2 + 65536;
  for (const auto& f : figures) size += f.size();
  page.reserve(size);
  for (const auto& f : figures) page += f;
  page += "<h2>Full table</h2>\n<pre>" + escapeHtml(table) + "</pre>\n";
  page += "<script type=\"application/json\" id=\"report-data\">";
  page += charts;
  page += "</script>\n";
  if (!library.empty()) page += "<script>" + library_script + "</script>\n";
  page += std::string("<script>") + kScript + "</script>\n</body></html>\n";
  return page;
}

}  // namespace uwbloc::eval
