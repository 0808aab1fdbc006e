// Per-call cost of Pinocchio's RNEA, CRBA and ABA on a URDF, printed as the JSON keys of
// `evoloop bench dynamics --json` (ns per call) so scripts/pinocchio_bench.py can put the two
// side by side in interleaved rounds. Built by that script against the `pin` wheel (Pinocchio
// 4.1.0) and `cmeel-eigen`, with -O3 -DNDEBUG and no -march (evoloop's release build targets the
// baseline x86-64 too).
//
//   pinocchio_bench FILE.urdf [CALLS]
//
// The states are 64 random (q, v, a, tau) in [-1, 1], cycled, as evoloop's side draws them;
// ns per call is the median of 10 batches, the algorithms taking turns batch by batch.
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <algorithm>
#include <chrono>
#include <functional>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

int main(int argc, char **argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s FILE.urdf [CALLS]\n", argv[0]);
    return 2;
  }
  const long calls = argc > 2 ? std::atol(argv[2]) : 200000;
  pinocchio::Model model;
  pinocchio::urdf::buildModel(argv[1], model);
  pinocchio::Data data(model);
  const int states = 64;
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto draw = [&]() {
    Eigen::VectorXd x(model.nv);
    for (int i = 0; i < model.nv; ++i) x[i] = u(rng);
    return x;
  };
  std::vector<Eigen::VectorXd> q, v, a, tau;
  for (int s = 0; s < states; ++s) {
    q.push_back(draw());
    v.push_back(draw());
    a.push_back(draw());
    tau.push_back(draw());
  }
  volatile double sink = 0.0;
  std::vector<std::function<void(int)>> algorithms = {
      [&](int s) { sink = sink + pinocchio::rnea(model, data, q[s], v[s], a[s])[0]; },
      [&](int s) { sink = sink + pinocchio::crba(model, data, q[s])(0, 0); },
      [&](int s) { sink = sink + pinocchio::aba(model, data, q[s], v[s], tau[s])[0]; },
  };
  // As evoloop's side: `batches` rounds of calls / batches calls of every algorithm in turn,
  // the median batch reported.
  const int batches = 10;
  const long per_batch = calls / batches > 0 ? calls / batches : 1;
  std::vector<std::vector<double>> ns(algorithms.size(), std::vector<double>(batches));
  for (auto &f : algorithms)
    for (long k = 0; k < per_batch; ++k) f(int(k % states));
  for (int b = 0; b < batches; ++b) {
    for (size_t i = 0; i < algorithms.size(); ++i) {
      auto &f = algorithms[i];
      const auto t0 = std::chrono::steady_clock::now();
      for (long k = 0; k < per_batch; ++k) f(int(k % states));
      const auto t1 = std::chrono::steady_clock::now();
      ns[i][b] = std::chrono::duration<double, std::nano>(t1 - t0).count() / double(per_batch);
    }
  }
  auto median = [](std::vector<double> x) {
    std::sort(x.begin(), x.end());
    const size_t n = x.size();
    return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
  };
  const double rnea = median(ns[0]), crba = median(ns[1]), aba = median(ns[2]);
  std::printf(
      "{\"library\": \"pinocchio\", \"joints\": %d, \"calls\": %ld, \"ns_per_call\": "
      "{\"rnea\": %.2f, \"crba\": %.2f, \"aba\": %.2f}}\n",
      model.nv, calls, rnea, crba, aba);
  return 0;
}
