#include "uwbloc/evaluation/benchmark_functions.hpp"

#include <cmath>
#include <stdexcept>

namespace uwbloc::optim {

std::vector<Benchmark> benchmarks(int dim) {
  auto box = [dim](double lo, double hi) {
    return Box{Eigen::VectorXd::Constant(dim, lo), Eigen::VectorXd::Constant(dim, hi)};
  };
  std::vector<Benchmark> out;
  out.push_back({"f1_sphere", box(-100, 100), 0.0,
                 [](const Eigen::Ref<const Eigen::VectorXd>& x) { return x.squaredNorm(); }});
  out.push_back(
      {"f2_schwefel_2.22", box(-10, 10), 0.0, [](const Eigen::Ref<const Eigen::VectorXd>& x) {
         return x.cwiseAbs().sum() + x.cwiseAbs().prod();
       }});
  out.push_back({"f3_step", box(-100, 100), 0.0, [](const Eigen::Ref<const Eigen::VectorXd>& x) {
                   double s = 0;
                   for (Eigen::Index i = 0; i < x.size(); ++i)
                     s += std::pow(std::floor(x(i) + 0.5), 2);
                   return s;
                 }});
  out.push_back(
      {"f4_rastrigin", box(-5.12, 5.12), 0.0, [](const Eigen::Ref<const Eigen::VectorXd>& x) {
         double s = 10.0 * x.size();
         for (Eigen::Index i = 0; i < x.size(); ++i)
           s += x(i) * x(i) - 10 * std::cos(2 * M_PI * x(i));
         return s;
       }});
  out.push_back(
      {"f5_griewank", box(-600, 600), 0.0, [](const Eigen::Ref<const Eigen::VectorXd>& x) {
         double p = 1.0;
         for (Eigen::Index i = 0; i < x.size(); ++i) p *= std::cos(x(i) / std::sqrt(i + 1.0));
         return x.squaredNorm() / 4000.0 - p + 1.0;
       }});
  Box mich{Eigen::Vector2d(-6, 0), Eigen::Vector2d(-1, 2)};
  out.push_back({"michalewicz", mich, -1.9668, [](const Eigen::Ref<const Eigen::VectorXd>& x) {
                   double s = 0;
                   for (Eigen::Index i = 0; i < x.size(); ++i)
                     s -= std::sin(x(i)) * std::pow(std::sin((i + 1) * x(i) * x(i) / M_PI), 20);
                   return s;
                 }});
  Box gp{Eigen::Vector2d(-2, -2), Eigen::Vector2d(2, 2)};
  out.push_back({"goldstein_price", gp, 3.0, [](const Eigen::Ref<const Eigen::VectorXd>& v) {
                   const double x = v(0), y = v(1);
                   const double a = 1 + std::pow(x + y + 1, 2) * (19 - 14 * x + 3 * x * x - 14 * y +
                                                                  6 * x * y + 3 * y * y);
                   const double b =
                       30 + std::pow(2 * x - 3 * y, 2) *
                                (18 - 32 * x + 12 * x * x + 48 * y - 36 * x * y + 27 * y * y);
                   return a * b;
                 }});
  return out;
}

Benchmark benchmark(const std::string& name, int dim) {
  for (auto& b : benchmarks(dim))
    if (b.name == name) return b;
  throw std::invalid_argument("unknown benchmark '" + name + "'");
}

}  // namespace uwbloc::optim
