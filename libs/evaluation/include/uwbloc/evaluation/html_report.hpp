// report.html: one self-contained page per run (no network): the table, the plots, and
// interactive charts drawn by Chart.js, inlined from Debian's libjs-chart.js.
#pragma once

#include <string>
#include <vector>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/evaluation/plots.hpp"
#include "uwbloc/evaluation/runner.hpp"

namespace uwbloc::eval {

/// Where Debian's libjs-chart.js puts Chart.js (UMD build): inlined into the report.
inline constexpr const char* kChartJsPath = "/usr/share/javascript/chart.js/chart.min.js";

/// The page. `table` is the console table; `plots` the pictures in `plots_dir`, inlined as data
/// URIs. With `chart_js` unreadable, the page says so and shows everything but the interactive
/// charts. When the page has loaded, its <body> carries data-report-status="ok" once every
/// interactive chart has drawn points (or "static" without Chart.js); any JavaScript error sets
/// it to "error: ...". The browser test (tests/browser/check_report.sh) reads that attribute.
/// The pictures and the charts' data are prepared on `jobs` threads; the page is the same.
std::string formatHtmlReport(const data::Dataset& dataset,
                             const std::vector<MethodSummary>& methods, const std::string& table,
                             const std::vector<PlotFile>& plots, const std::string& plots_dir,
                             const std::string& chart_js = kChartJsPath, int jobs = 1);

}  // namespace uwbloc::eval
