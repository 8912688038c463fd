/**
 * @file identification.cpp
 * @brief Ceres and closed-form identification of the displacement models.
 */
#include "pedicle_drilling/core/breathing/identification.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include <Eigen/Dense>

namespace pedicle_drilling::core {

namespace {

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

std::vector<double> timeDerivative(const std::vector<double>& t, const std::vector<double>& x) {
  if (t.size() != x.size()) throw std::invalid_argument("timeDerivative: size mismatch");
  const size_t n = t.size();
  if (n < 2) throw std::invalid_argument("timeDerivative: need at least 2 samples");
  for (size_t i = 1; i < n; ++i) {
    if (!(t[i] > t[i - 1])) throw std::invalid_argument("timeDerivative: non-increasing time");
  }
  std::vector<double> dx(n);
  dx[0] = (x[1] - x[0]) / (t[1] - t[0]);
  dx[n - 1] = (x[n - 1] - x[n - 2]) / (t[n - 1] - t[n - 2]);
  for (size_t i = 1; i + 1 < n; ++i) {
    // Second-order central difference valid for non-uniform spacing.
    const double h0 = t[i] - t[i - 1];
    const double h1 = t[i + 1] - t[i];
    dx[i] = (h0 * h0 * (x[i + 1] - x[i]) + h1 * h1 * (x[i] - x[i - 1])) / (h0 * h1 * (h0 + h1));
  }
  return dx;
}

double rSquared(const std::vector<double>& measured, const std::vector<double>& predicted) {
  if (measured.size() != predicted.size() || measured.empty()) {
    throw std::invalid_argument("rSquared: sizes differ or empty");
  }
  double mean = 0.0;
  for (double g : measured) mean += g;
  mean /= static_cast<double>(measured.size());
  double ss_res = 0.0;
  double ss_tot = 0.0;
  for (size_t i = 0; i < measured.size(); ++i) {
    ss_res += (measured[i] - predicted[i]) * (measured[i] - predicted[i]);
    ss_tot += (measured[i] - mean) * (measured[i] - mean);
  }
  if (ss_tot <= 0.0) return 0.0;
  return 1.0 - ss_res / ss_tot;
}

double rootMeanSquareError(const std::vector<double>& measured,
                           const std::vector<double>& predicted) {
  if (measured.size() != predicted.size() || measured.empty()) {
    throw std::invalid_argument("rootMeanSquareError: sizes differ or empty");
  }
  double s = 0.0;
  for (size_t i = 0; i < measured.size(); ++i) {
    s += (measured[i] - predicted[i]) * (measured[i] - predicted[i]);
  }
  return std::sqrt(s / static_cast<double>(measured.size()));
}

std::vector<double> predictAll(const AxisModel& model, const AxisSamples& samples) {
  std::vector<double> p(samples.d.size());
  const bool rate = model.kind == ModelKind::kHysteresis;
  for (size_t i = 0; i < p.size(); ++i) {
    p[i] = model.predict(samples.tv[i], rate ? samples.dtv_dt[i] : 0.0);
  }
  return p;
}

void evaluateFit(const AxisSamples& samples, FitResult* result) {
  const std::vector<double> p = predictAll(result->model, samples);
  result->r2 = rSquared(samples.d, p);
  result->rmse = rootMeanSquareError(samples.d, p);
}

void checkSamples(ModelKind kind, const AxisSamples& s) {
  if (s.tv.size() != s.d.size()) {
    throw std::invalid_argument("identification: tv and displacement sizes differ");
  }
  if (kind == ModelKind::kHysteresis && s.dtv_dt.size() != s.d.size()) {
    throw std::invalid_argument("identification: hysteresis model needs dTv/dt for every sample");
  }
  if (static_cast<int>(s.d.size()) < numCoefficients(kind) + 1) {
    throw std::invalid_argument("identification: too few samples (" + std::to_string(s.d.size()) +
                                ")");
  }
  for (size_t i = 0; i < s.d.size(); ++i) {
    bool ok = std::isfinite(s.tv[i]) && std::isfinite(s.d[i]);
    if (kind == ModelKind::kHysteresis) ok = ok && std::isfinite(s.dtv_dt[i]);
    if (!ok) {
      throw std::invalid_argument("identification: non-finite sample at index " +
                                  std::to_string(i));
    }
  }
}

FitResult fitOls(ModelKind kind, const AxisSamples& samples) {
  checkSamples(kind, samples);
  const auto start = std::chrono::steady_clock::now();
  const int n = static_cast<int>(samples.d.size());
  const int p = numCoefficients(kind);
  Eigen::MatrixXd a(n, p);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) {
    a(i, 0) = samples.tv[i];
    if (kind == ModelKind::kHysteresis) a(i, 1) = samples.dtv_dt[i];
    a(i, p - 1) = 1.0;
    b(i) = samples.d[i];
  }
  const Eigen::VectorXd x = a.colPivHouseholderQr().solve(b);
  FitResult result;
  result.model.kind = kind;
  result.model.setCoefficients(std::vector<double>(x.data(), x.data() + p));
  result.time_s = secondsSince(start);
  result.method = "ols";
  result.converged = x.allFinite();
  evaluateFit(samples, &result);
  return result;
}

FitResult fitCeres(ModelKind kind, const AxisSamples& samples, const CeresFitOptions& options) {
  checkSamples(kind, samples);
  const auto start = std::chrono::steady_clock::now();
  std::vector<double> q(static_cast<size_t>(numCoefficients(kind)), 0.0);
  ceres::Problem problem;
  problem.AddResidualBlock(kind == ModelKind::kLinear
                               ? DisplacementBatchResidual<2>::Create(samples)
                               : DisplacementBatchResidual<3>::Create(samples),
                           nullptr, q.data());
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.initial_trust_region_radius = options.initial_trust_region_radius;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  solver_options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);

  FitResult result;
  result.model.kind = kind;
  result.model.setCoefficients(q);
  result.time_s = secondsSince(start);
  result.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  result.method = "ceres";
  result.converged = summary.IsSolutionUsable() && summary.termination_type == ceres::CONVERGENCE;
  evaluateFit(samples, &result);
  return result;
}

}  // namespace pedicle_drilling::core
