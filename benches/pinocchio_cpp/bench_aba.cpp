// Pinocchio's C++ on the same models as orbitflex's `examples/bench_cpp_match.rs`
// (BENCHMARKS.md, "Rust against Pinocchio's C++"). Built by `run.sh` against the headers and
// libraries of the `pin` wheel, in several configurations (compiler, -march; see run.sh). With
// -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION (the `wheel` build) the algorithms are not compiled
// here: the calls go to the explicit instantiations for double inside libpinocchio_default.so.
//
//   bench_aba <urdf> <ee_link or -> [locked joint ...] [--only NAME,NAME...] [--blocks N] [--iters N]
//
// The URDF's root becomes a free-flyer joint (orbitflex's floating base); gravity is zero.
// Prints one line per measurement: `<name> <median ns per call>`, the median over blocks.
// `--iters N` replaces every measurement's number of calls per block (the warm-up is N/10 calls);
// callgrind.sh uses it with two values of `--blocks` to count the instructions of one call.
// Inputs are the same deterministic numbers as the Rust program: q_i = 0.3 sin(i+1),
// q̇_i = 0.2 cos(i+1), base twist [v; ω] = [0.01, -0.02, 0.03; 0.05, -0.04, 0.03], τ_i = 1 + 0.1 i.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/parsers/urdf.hpp>

using pinocchio::Data;
using pinocchio::Model;
using Vec = Eigen::VectorXd;
// Every algorithm gets its vectors as Eigen::Ref<const VectorXd>: the argument type of the
// library's explicit instantiations, so that the `wheel` build calls them instead of compiling
// its own copy. The header-only builds compile the same call (Pinocchio converts to Ref inside
// most algorithms anyway).
using CRef = Eigen::Ref<const Vec>;

static volatile double sink = 0.0;

// Median over `blocks` blocks of the mean time per call (ns) of `iters` calls of `f`.
static int g_blocks = 15;
static int g_iters = 0; // 0: each measurement's own count

template<typename F>
double median_ns(F && f, int iters, int blocks = g_blocks)
{
  std::vector<double> t;
  if (g_iters > 0)
    iters = g_iters;
  for (int i = 0; i < iters / 10; ++i)
    f(); // warm-up
  for (int b = 0; b < blocks; ++b)
  {
    auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < iters; ++i)
      f();
    auto t1 = std::chrono::steady_clock::now();
    t.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / iters);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

// Flexible joints (model §3, §4) on Pinocchio: x = [q_pin (nq) | θ (n) | v_pin (nv) | θ̇ (n)],
// the free-flyer configuration [r; quat (x,y,z,w)] and velocity [v; ω] in the base frame.
// With Pinocchio's spatial base acceleration, d/dt of the base-frame components of (v, ω) is
// aba's a[0:6] (model §6.5). The same derivative and RK4 as orbitflex's FlexibleArm::step.
struct FlexArm
{
  const Model & model;
  Data data;
  int n, nq, nv;
  Vec k, d, j, beta, tau, k1, k2, k3, k4, trial;

  FlexArm(const Model & m)
  : model(m), data(m), n(m.nv - 6), nq(m.nq), nv(m.nv)
  {
    k = Vec::Constant(n, 2e4);
    d = Vec::Constant(n, 2.0);
    j = Vec::Constant(n, 160.0 * 160.0 * 4e-5);
    beta = Vec::Constant(n, 1.0);
    tau = Vec::Zero(nv);
    const int len = nq + n + nv + n;
    k1 = k2 = k3 = k4 = trial = Vec::Zero(len);
  }

  void derivative(const Vec & x, const Vec & u, Vec & xd)
  {
    const auto q = x.segment(0, nq);
    const auto theta = x.segment(nq, n);
    const auto v = x.segment(nq + n, nv);
    const auto theta_dot = x.segment(nq + n + nv, n);
    // τ = k (θ − q) + d (θ̇ − q̇); the base is unactuated.
    tau.head<6>().setZero();
    tau.tail(n).array() = k.array() * (theta - q.tail(n)).array()
                          + d.array() * (theta_dot - v.tail(n)).array();
    const Vec & a = pinocchio::aba(model, data, CRef(q), CRef(v), CRef(tau));
    const Eigen::Quaterniond quat(x[6], x[3], x[4], x[5]);
    const Eigen::Vector3d omega = v.segment<3>(3);
    xd.segment<3>(0) = quat.toRotationMatrix() * v.head<3>();
    const Eigen::Vector3d qv(x[3], x[4], x[5]);
    xd.segment<3>(3) = 0.5 * (x[6] * omega + qv.cross(omega));
    xd[6] = -0.5 * qv.dot(omega);
    xd.segment(7, n) = v.tail(n);
    xd.segment(nq, n) = theta_dot;
    xd.segment(nq + n, nv) = a;
    xd.segment(nq + n + nv, n).array() =
      (u.array() - tau.tail(n).array() - beta.array() * theta_dot.array()) / j.array();
  }

  void step(Vec & x, double dt, const Vec & u)
  {
    derivative(x, u, k1);
    trial = x + 0.5 * dt * k1;
    derivative(trial, u, k2);
    trial = x + 0.5 * dt * k2;
    derivative(trial, u, k3);
    trial = x + dt * k3;
    derivative(trial, u, k4);
    x += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    x.segment<4>(3).normalize();
  }
};

int main(int argc, char ** argv)
{
  if (argc < 3)
  {
    std::fprintf(stderr, "usage: %s <urdf> <ee_link or -> [locked joint ...]\n", argv[0]);
    return 2;
  }
  std::string only;
  std::vector<std::string> locked_names;
  for (int a = 3; a < argc; ++a)
  {
    const std::string arg = argv[a];
    if (arg == "--only" && a + 1 < argc)
      only = "," + std::string(argv[++a]) + ",";
    else if (arg == "--blocks" && a + 1 < argc)
      g_blocks = std::atoi(argv[++a]);
    else if (arg == "--iters" && a + 1 < argc)
      g_iters = std::atoi(argv[++a]);
    else
      locked_names.push_back(arg);
  }
  const auto wanted = [&](const char * name) {
    return only.empty() || only.find("," + std::string(name) + ",") != std::string::npos;
  };
  Model full;
  pinocchio::urdf::buildModel(argv[1], pinocchio::JointModelFreeFlyer(), full);
  std::vector<pinocchio::JointIndex> locked;
  for (const auto & name : locked_names)
  {
    if (!full.existJointName(name))
    {
      std::fprintf(stderr, "no joint %s in %s\n", name.c_str(), argv[1]);
      return 2;
    }
    locked.push_back(full.getJointId(name));
  }
  Model model =
    locked.empty() ? full : pinocchio::buildReducedModel(full, locked, pinocchio::neutral(full));
  model.gravity.setZero();
  Data data(model);
  const int n = model.nv - 6;

  Vec q = pinocchio::neutral(model), v = Vec::Zero(model.nv), tau = Vec::Zero(model.nv);
  for (int i = 0; i < n; ++i)
  {
    q[7 + i] = 0.3 * std::sin(i + 1.0);
    v[6 + i] = 0.2 * std::cos(i + 1.0);
    tau[6 + i] = 1.0 + 0.1 * i;
  }
  v.head<6>() << 0.01, -0.02, 0.03, 0.05, -0.04, 0.03;
  const Vec a = Vec::Constant(model.nv, 0.1);

  std::printf("model %s nq %d nv %d n %d\n", argv[1], model.nq, model.nv, n);
  // The joint accelerations and one RK4 step's (q, θ) for run.sh's agreement check.
  const CRef qr(q), vr(v), taur(tau), ar(a);
  const Vec qdd = pinocchio::aba(model, data, qr, vr, taur).tail(n);
  std::printf("check_qdd");
  for (int i = 0; i < n; ++i)
    std::printf(" %.15e", qdd[i]);
  std::printf("\n");
  const auto report = [&](const char * name, int iters, auto && f) {
    if (wanted(name))
      std::printf("%s %.1f\n", name, median_ns(f, iters));
  };
  using pinocchio::Convention;
  report("aba_local", 20000, [&] { sink += pinocchio::aba(model, data, qr, vr, taur, Convention::LOCAL)[0]; });
  report("aba_world", 20000, [&] { sink += pinocchio::aba(model, data, qr, vr, taur, Convention::WORLD)[0]; });
  report("rnea", 20000, [&] { sink += pinocchio::rnea(model, data, qr, vr, ar)[0]; });
  report("crba_local", 20000, [&] { sink += pinocchio::crba(model, data, qr, Convention::LOCAL)(0, 0); });
  report("crba_world", 20000, [&] { sink += pinocchio::crba(model, data, qr, Convention::WORLD)(0, 0); });
  report("aba_derivatives", 4000, [&] {
    pinocchio::computeABADerivatives(model, data, qr, vr, taur);
    sink += data.ddq_dq(0, 0);
  });
  report("rnea_derivatives", 4000, [&] {
    pinocchio::computeRNEADerivatives(model, data, qr, vr, ar);
    sink += data.dtau_dq(0, 0);
  });

  FlexArm arm(model);
  Vec x0 = Vec::Zero(model.nq + n + model.nv + n);
  x0.head(model.nq) = q;
  x0.segment(model.nq, n) = q.tail(n);
  x0.segment(model.nq + n, model.nv) = v;
  Vec x = x0;
  const Vec u = Vec::Constant(n, 1.0);
  arm.step(x, 1e-3, u);
  std::printf("check_step");
  for (int i = 0; i < 2 * n; ++i)
    std::printf(" %.15e", x[7 + i]);
  std::printf("\n");
  report("rk4_step", 5000, [&] {
    x = x0;
    arm.step(x, 1e-3, u);
    sink += x[0];
  });
  return 0;
}
