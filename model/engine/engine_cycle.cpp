#include "model/engine/engine_cycle.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace noisemon::model::engine {

namespace {

constexpr double kUniversalGasConstant = 8.3143;  // J/(mol K), as in the Hardenberg-Hase fit

// Woschni (Heywood, ch. 12): h = 3.26 B^-0.2 p[kPa]^0.8 T^-0.55 w^0.8,
// w = C1 Sp + C2 (Vd Tr / (pr Vr)) (p - p_motored), C1 = 2.28, C2 = 3.24e-3 m/(s K) after start of combustion.
constexpr double kWoschniC1 = 2.28;
constexpr double kWoschniC2 = 3.24e-3;
constexpr double kMotoredPolytropic = 1.35;

std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

double uniform01(std::uint64_t& state) {  // (0, 1]
  return (static_cast<double>(splitmix64(state) >> 11) + 1.0) * 0x1.0p-53;
}

}  // namespace

// ---------------------------------------------------------------------------------------------- fuelling

CycleVariation draw_cycle_variation(std::uint64_t seed, std::int64_t cycle, double relative_sigma) {
  std::uint64_t state = seed;
  state = splitmix64(state) ^ static_cast<std::uint64_t>(cycle);
  splitmix64(state);
  const double r1 = std::sqrt(-2.0 * std::log(uniform01(state)));
  const double a1 = 2.0 * kPi * uniform01(state);
  const double n1 = std::clamp(r1 * std::cos(a1), -4.0, 4.0);
  const double n2 = std::clamp(r1 * std::sin(a1), -4.0, 4.0);
  CycleVariation v{1.0 + relative_sigma * n1, 1.0 + relative_sigma * n2, {}};
  for (auto& phase : v.ringing_phase_rad) phase = 2.0 * kPi * uniform01(state);  // drawn after: n1, n2 unchanged
  return v;
}

double friction_mep_pa(const EngineGeometry& geometry, double speed_rpm) {
  // Chen-Flynn: FMEP = C + PF pmax + MPSF Sp + MPSSF Sp^2 [bar]; the pmax term taken at a typical 80 bar.
  const double sp = geometry.mean_piston_speed_m_s(speed_rpm);
  return 1e5 * (0.25 + 0.005 * 80.0 + 0.09 * sp + 0.0009 * sp * sp);
}

double fuel_mass_per_cycle_kg(const EngineCycleParams& params, const OperatingCondition& op) {
  if (op.motored) return 0.0;
  const double vd = params.geometry.displacement_m3();
  const double bmep = 4.0 * kPi * std::max(op.load_nm, 0.0) / vd;  // four-stroke
  const double imep = bmep + friction_mep_pa(params.geometry, op.speed_rpm);
  return imep * vd / (params.assumed_indicated_efficiency * params.fuel_lhv_j_kg * params.combustion_efficiency);
}

// ---------------------------------------------------------------------------------------------- cycle

// Per-compute() constants of the rate function.
struct EngineCycle::Constants {
  double m, r, cv0, cv1, tw, deg_per_s, a, mp, md, cn_ea, hh_speed, p_motored_ref;
  double woschni_w0;    // C1 Sp, m/s
  double woschni_coef;  // scale * 3.26 B^-0.2 (m R / 1000)^0.8 / (deg/s): times A V^-0.8 T^0.25 w^0.8 (T - Tw)
};

struct EngineCycle::Combustion {
  double soi = 0;         // deg
  bool injected = false;  // fuel this cycle
  bool ignited = false;
  double soc = 0;
  double delay_scale = 1;
  double q_premixed = 0, q_diffusion = 0;  // J
  double dur_p = 1, dur_d = 1;
  double woschni_k = 0;  // C2 Vd Tr / (pr Vr)
  double woschni_w = 0;  // C1 Sp
};

struct EngineCycle::Rates {
  double dtemp;  // K/deg
  double htr;    // heat loss rate, J/deg
  double pdv;    // p dV/dtheta, J/deg
  double dign;   // Livengood-Wu integrand, 1/deg
  double hrr;    // heat release rate, J/deg
  double p;      // Pa
};

EngineCycle::EngineCycle(const EngineCycleParams& params) : params_(params) {
  const auto& g = params_.geometry;
  if (!(params_.step_deg > 0.0 && params_.step_deg <= 1.0))
    throw std::invalid_argument("EngineCycle: step_deg must be in (0, 1]");
  if (!(params_.ivc_deg > -360.0 && params_.ivc_deg < -90.0 && params_.evo_deg > 90.0 && params_.evo_deg < 340.0))
    throw std::invalid_argument("EngineCycle: IVC must be in (-360, -90) and EVO in (90, 340) deg");
  if (!(g.compression_ratio > 1.0 && g.conrod_m > 0.5 * g.stroke_m && g.bore_m > 0.0))
    throw std::invalid_argument("EngineCycle: invalid geometry");
  const auto steps = static_cast<std::size_t>(std::lround(720.0 / params_.step_deg));
  h_ = 720.0 / static_cast<double>(steps);
  nodes_ = steps + 1;
  ivc_node_ = static_cast<std::size_t>(std::lround((params_.ivc_deg + 360.0) / h_));
  evo_node_ = static_cast<std::size_t>(std::lround((params_.evo_deg + 360.0) / h_));

  const std::size_t half = 2 * steps + 1;
  vol_.resize(half);
  dvol_.resize(half);
  area_v08_.resize(half);
  motored_ratio_.resize(half);
  const double v_ivc = g.volume_m3(-360.0 + h_ * static_cast<double>(ivc_node_));
  for (std::size_t j = 0; j < half; ++j) {
    const double th = -360.0 + 0.5 * h_ * static_cast<double>(j);
    vol_[j] = g.volume_m3(th);
    dvol_[j] = g.dvolume_m3_per_deg(th);
    area_v08_[j] = g.wall_area_m2(th) * std::pow(vol_[j], -0.8);
    motored_ratio_[j] = std::pow(v_ivc / vol_[j], kMotoredPolytropic);
  }
  p_.assign(nodes_, params_.intake_pressure_pa);
  dp_.assign(nodes_, 0.0);
  pt_ = p_;
  dpt_ = dp_;
  const std::size_t closed = evo_node_ - ivc_node_ + 1;
  closed_angle_.resize(closed);
  closed_temperature_.resize(closed);
  hrr_.resize(closed);
  htr_.resize(closed);
  ring_scratch_.resize(2 * closed);
  for (std::size_t i = 0; i < closed; ++i) closed_angle_[i] = -360.0 + h_ * static_cast<double>(ivc_node_ + i);
  compute(OperatingCondition{.speed_rpm = 1000.0, .load_nm = 0.0, .soi_deg_btdc = 0.0, .motored = true});
}

std::span<const double> EngineCycle::closed_pressure_pa() const {
  return {p_.data() + ivc_node_, evo_node_ - ivc_node_ + 1};
}

double EngineCycle::speed_of_sound_m_s(double temperature_k) const {
  return gas_speed_of_sound_m_s(temperature_k, params_.gas_constant_j_kg_k, params_.cv0_j_kg_k, params_.cv1_j_kg_k2);
}

double EngineCycle::internal_energy_j_kg(double temperature_k) const {
  return params_.cv0_j_kg_k * temperature_k + 0.5 * params_.cv1_j_kg_k2 * temperature_k * temperature_k;
}

// The right-hand side of the first law at half-step index j (angle -360 + j h / 2).
EngineCycle::Rates EngineCycle::rates(std::size_t j, double temp, const Constants& k, const Combustion& c) const {
  const double th = -360.0 + 0.5 * h_ * static_cast<double>(j);
  const double v = vol_[j];
  const double p = k.m * k.r * temp / v;
  Rates out{};
  out.p = p;
  out.pdv = p * dvol_[j];

  const bool burning = c.ignited && th > c.soc;
  if (burning) {
    // Wiebe rate: Q a (m + 1) / D x^m exp(-a x^(m + 1)), x = (theta - soc) / D.
    const double xp = (th - c.soc) / c.dur_p;
    const double xd = (th - c.soc) / c.dur_d;
    const double xpm = std::exp(k.mp * std::log(xp)), xdm = std::exp(k.md * std::log(xd));
    const double ep = k.a * xpm * xp, ed = k.a * xdm * xd;
    if (ep < 50.0) out.hrr += c.q_premixed * k.a * (k.mp + 1.0) / c.dur_p * xpm * std::exp(-ep);
    if (ed < 50.0) out.hrr += c.q_diffusion * k.a * (k.md + 1.0) / c.dur_d * xdm * std::exp(-ed);
  }
  if (k.woschni_coef > 0.0) {
    // Woschni: p^0.8 T^-0.55 = (m R / V)^0.8 T^0.25; the V and m R factors are tabulated or per cycle.
    double w08 = k.woschni_w0;  // w^0.8 while only the motion term applies
    if (burning) {
      const double w = c.woschni_w + c.woschni_k * std::max(p - k.p_motored_ref * motored_ratio_[j], 0.0);
      w08 = std::exp(0.8 * std::log(w));
    }
    out.htr = k.woschni_coef * area_v08_[j] * std::sqrt(std::sqrt(temp)) * w08 * (temp - k.tw);
  }
  if (c.injected && !c.ignited && th >= c.soi) {
    // Hardenberg-Hase (Heywood, ch. 10) delay in crank degrees at the local p, T.
    const double p_bar = 1e-5 * p;
    if (p_bar > 12.5) {
      const double tau = k.hh_speed * std::exp(k.cn_ea * (1.0 / (kUniversalGasConstant * temp) - 1.0 / 17190.0) +
                                               std::pow(21.2 / (p_bar - 12.4), 0.63));
      out.dign = 1.0 / (tau * c.delay_scale);
    }
  }
  out.dtemp = (out.hrr - out.htr - out.pdv) / (k.m * (k.cv0 + k.cv1 * temp));
  return out;
}

// The rate function's constants for this cycle: trapped mass m (at IVC), mean piston speed sp.
EngineCycle::Constants EngineCycle::constants(const OperatingCondition& op, double m, double sp) const {
  return Constants{.m = m,
                   .r = params_.gas_constant_j_kg_k,
                   .cv0 = params_.cv0_j_kg_k,
                   .cv1 = params_.cv1_j_kg_k2,
                   .tw = params_.wall_temperature_k,
                   .deg_per_s = 6.0 * op.speed_rpm,
                   .a = params_.wiebe_a,
                   .mp = params_.premixed_shape,
                   .md = params_.diffusion_shape,
                   .cn_ea = 618840.0 / (params_.cetane_number + 25.0),
                   .hh_speed = 0.36 + 0.22 * sp,
                   .p_motored_ref = params_.intake_pressure_pa,
                   .woschni_w0 = std::pow(kWoschniC1 * sp, 0.8),
                   .woschni_coef = params_.heat_transfer_scale * 3.26 * std::pow(params_.geometry.bore_m, -0.2) *
                                   std::pow(1e-3 * m * params_.gas_constant_j_kg_k, 0.8) / (6.0 * op.speed_rpm)};
}

// Starts the cycle's summary (mass, fuel, timing; no combustion yet) and its combustion state before ignition.
EngineCycle::Combustion EngineCycle::start_cycle(const OperatingCondition& op, const CycleVariation& variation,
                                                 double m, double sp) {
  const double v_ivc = vol_[2 * ivc_node_];
  const double fuel = fuel_mass_per_cycle_kg(params_, op) * std::max(variation.heat_release_scale, 0.0);
  summary_ = CycleSummary{};
  summary_.trapped_mass_kg = m;
  summary_.fuel_mass_kg = fuel;
  summary_.fuel_energy_j = fuel * params_.fuel_lhv_j_kg * params_.combustion_efficiency;
  summary_.equivalence_ratio = fuel * params_.stoichiometric_afr / m;
  summary_.soi_deg = -op.soi_deg_btdc;
  summary_.soc_deg = std::numeric_limits<double>::quiet_NaN();
  summary_.ignition_delay_deg = std::numeric_limits<double>::quiet_NaN();

  Combustion c;
  c.soi = std::max(-op.soi_deg_btdc, params_.ivc_deg);
  c.injected = fuel > 0.0;
  c.delay_scale = std::max(variation.ignition_delay_scale, 0.05);
  c.woschni_w = kWoschniC1 * sp;
  c.woschni_k = kWoschniC2 * params_.geometry.displacement_m3() * params_.intake_temperature_k /
                (params_.intake_pressure_pa * v_ivc);
  return c;
}

// Combustion starts at soc: the premixed and diffusion burns, split by Watson's premixed fraction.
void EngineCycle::ignite(Combustion& c, double soc, double deg_per_s) {
  c.soc = soc;
  c.ignited = true;
  const double delay_ms = 1e3 * (c.soc - c.soi) / deg_per_s;
  const double phi = summary_.equivalence_ratio;
  // Watson's premixed fraction: beta = 1 - 0.926 phi^0.37 / tau_id[ms]^0.26.
  const double beta = std::clamp(1.0 - 0.926 * std::pow(phi, 0.37) / std::pow(delay_ms, 0.26), 0.05, 0.95);
  c.q_premixed = beta * summary_.fuel_energy_j;
  c.q_diffusion = (1.0 - beta) * summary_.fuel_energy_j;
  c.dur_p = params_.premixed_duration_deg;
  c.dur_d = params_.diffusion_duration_base_deg + params_.diffusion_duration_per_phi_deg * phi;
  summary_.soc_deg = c.soc;
  summary_.ignition_delay_deg = c.soc - c.soi;
  summary_.premixed_fraction = beta;
}

// RK4 over the closed part (IVC..EVO); state: T, heat loss, work, ignition integral. Fills the closed-part traces
// and the pressure table there, ignites where the ignition integral reaches 1.
void EngineCycle::integrate_closed_part(const Constants& k, Combustion& c) {
  double temp = params_.intake_temperature_k, qloss = 0.0, work = 0.0, ign = 0.0;
  const double h = h_;
  for (std::size_t i = ivc_node_;; ++i) {
    const std::size_t ci = i - ivc_node_;
    const Rates k1 = rates(2 * i, temp, k, c);
    closed_temperature_[ci] = temp;
    hrr_[ci] = k1.hrr;
    htr_[ci] = k1.htr;
    p_[i] = k1.p;
    dp_[i] = k1.p * (k1.dtemp / temp - dvol_[2 * i] / vol_[2 * i]);
    if (i == evo_node_) break;
    const Rates k2 = rates(2 * i + 1, temp + 0.5 * h * k1.dtemp, k, c);
    const Rates k3 = rates(2 * i + 1, temp + 0.5 * h * k2.dtemp, k, c);
    const Rates k4 = rates(2 * i + 2, temp + h * k3.dtemp, k, c);
    temp += h / 6.0 * (k1.dtemp + 2.0 * (k2.dtemp + k3.dtemp) + k4.dtemp);
    qloss += h / 6.0 * (k1.htr + 2.0 * (k2.htr + k3.htr) + k4.htr);
    work += h / 6.0 * (k1.pdv + 2.0 * (k2.pdv + k3.pdv) + k4.pdv);
    if (c.injected && !c.ignited) {
      const double ign_next = ign + h / 6.0 * (k1.dign + 2.0 * (k2.dign + k3.dign) + k4.dign);
      if (ign_next >= 1.0) {
        const double th0 = -360.0 + h * static_cast<double>(i);
        ignite(c, th0 + h * (1.0 - ign) / (ign_next - ign), k.deg_per_s);
      }
      ign = ign_next;
    }
  }
  summary_.heat_loss_j = qloss;
  summary_.closed_work_j = work;
}

void EngineCycle::compute(const OperatingCondition& op, const CycleVariation& variation) {
  const double v_ivc = vol_[2 * ivc_node_];
  const double m = params_.intake_pressure_pa * v_ivc / (params_.gas_constant_j_kg_k * params_.intake_temperature_k);
  const double sp = params_.geometry.mean_piston_speed_m_s(op.speed_rpm);
  const Constants k = constants(op, m, sp);
  Combustion c = start_cycle(op, variation, m, sp);
  integrate_closed_part(k, c);
  if (c.ignited) {
    const double a = params_.wiebe_a;
    const double x = params_.evo_deg - c.soc;
    summary_.heat_release_j =
        c.q_premixed * (1.0 - std::exp(-a * std::pow(x / c.dur_p, params_.premixed_shape + 1.0))) +
        c.q_diffusion * (1.0 - std::exp(-a * std::pow(x / c.dur_d, params_.diffusion_shape + 1.0)));
  }
  fill_open_part();
  summarise();
  add_ringing(k.deg_per_s, variation, c);
}

// The true pressure table: the single zone plus the gas ringing of this cycle (closed part only).
void EngineCycle::add_ringing(double deg_per_s, const CycleVariation& variation, const Combustion& c) {
  std::copy(p_.begin(), p_.end(), pt_.begin());
  std::copy(dp_.begin(), dp_.end(), dpt_.begin());
  if (!c.ignited || !params_.ringing.active()) return;
  const std::size_t closed = evo_node_ - ivc_node_ + 1;
  const double peak_deg = c.soc + premixed_peak_fraction(params_.wiebe_a, params_.premixed_shape) * c.dur_p;
  RingingInput in;
  in.angle_deg = closed_angle_;
  in.temperature_k = closed_temperature_;
  in.deg_per_s = deg_per_s;
  in.soc_deg = c.soc;
  in.premixed_j = c.q_premixed;
  in.premixed_duration_deg = c.dur_p;
  in.wiebe_a = params_.wiebe_a;
  in.premixed_shape = params_.premixed_shape;
  in.volume_at_peak_m3 = params_.geometry.volume_m3(peak_deg);
  in.bore_m = params_.geometry.bore_m;
  in.gas_constant = params_.gas_constant_j_kg_k;
  in.cv0 = params_.cv0_j_kg_k;
  in.cv1 = params_.cv1_j_kg_k2;
  in.phase_rad = variation.ringing_phase_rad;
  summary_.ringing_amplitude_pa =
      add_gas_ringing(params_.ringing, in, std::span<double>(pt_).subspan(ivc_node_, closed),
                      std::span<double>(dpt_).subspan(ivc_node_, closed), ring_scratch_);
}

void EngineCycle::fill_open_part() {
  const double p_int = params_.intake_pressure_pa, p_exh = params_.exhaust_pressure_pa;
  for (std::size_t i = 0; i < ivc_node_; ++i) {
    p_[i] = p_int;
    dp_[i] = 0.0;
  }
  // Blowdown: the closed expansion continued with the local polytropic exponent at EVO (so p and dp/dtheta are
  // continuous), its excess over the exhaust pressure fading as a Gaussian of the angle after EVO.
  const double p_evo = p_[evo_node_], v_evo = vol_[2 * evo_node_], dv_evo = dvol_[2 * evo_node_];
  const double n = std::clamp(-dp_[evo_node_] * v_evo / (p_evo * dv_evo), 1.0, 1.7);
  const double th_evo = -360.0 + h_ * static_cast<double>(evo_node_);
  const double width = params_.blowdown_deg;
  const double blend_start = 340.0, blend_width = 360.0 - blend_start;
  for (std::size_t i = evo_node_ + 1; i < nodes_; ++i) {
    const double th = -360.0 + h_ * static_cast<double>(i);
    const double x = (th - th_evo) / width;
    double p = p_exh, dp = 0.0;
    if (x < 6.5) {
      const double w = std::exp(-x * x);
      const double v = vol_[2 * i];
      const double p_cl = p_evo * std::pow(v_evo / v, n);
      const double dp_cl = -n * p_cl * dvol_[2 * i] / v;
      p += (p_cl - p_exh) * w;
      dp += dp_cl * w + (p_cl - p_exh) * (-2.0 * x / width) * w;
    }
    if (th > blend_start) {  // exhaust -> intake (valve overlap), smoothstep so dp/dtheta stays continuous
      const double s = (th - blend_start) / blend_width;
      p += (p_int - p_exh) * s * s * (3.0 - 2.0 * s);
      dp += (p_int - p_exh) * 6.0 * s * (1.0 - s) / blend_width;
    }
    p_[i] = p;
    dp_[i] = dp;
  }
}

void EngineCycle::summarise() {
  std::size_t peak = ivc_node_;
  double max_dp = -std::numeric_limits<double>::infinity();
  for (std::size_t i = ivc_node_; i <= evo_node_; ++i) {
    if (p_[i] > p_[peak]) peak = i;
    max_dp = std::max(max_dp, dp_[i]);
  }
  summary_.peak_pressure_pa = p_[peak];
  summary_.peak_pressure_deg = -360.0 + h_ * static_cast<double>(peak);
  summary_.max_dp_dtheta_pa_per_deg = max_dp;
  // Indicated work by the trapezoid rule on the table (compression + expansion, and the whole cycle).
  const std::size_t bdc0 = static_cast<std::size_t>(std::lround(180.0 / h_));
  const std::size_t bdc1 = static_cast<std::size_t>(std::lround(540.0 / h_));
  double gross = 0.0, net = 0.0;
  for (std::size_t i = 0; i + 1 < nodes_; ++i) {
    const double dw = 0.5 * (p_[i] + p_[i + 1]) * (vol_[2 * i + 2] - vol_[2 * i]);
    net += dw;
    if (i >= bdc0 && i < bdc1) gross += dw;
  }
  const double vd = params_.geometry.displacement_m3();
  summary_.imep_gross_pa = gross / vd;
  summary_.imep_net_pa = net / vd;
}

double EngineCycle::pressure_pa(double theta_deg) const {
  const double u = std::clamp((theta_deg + 360.0) / h_, 0.0, static_cast<double>(nodes_ - 1));
  std::size_t i = static_cast<std::size_t>(u);
  if (i >= nodes_ - 1) i = nodes_ - 2;
  const double s = u - static_cast<double>(i);
  const double s2 = s * s, s3 = s2 * s;
  return (2 * s3 - 3 * s2 + 1) * pt_[i] + (s3 - 2 * s2 + s) * h_ * dpt_[i] + (-2 * s3 + 3 * s2) * pt_[i + 1] +
         (s3 - s2) * h_ * dpt_[i + 1];
}

}  // namespace noisemon::model::engine
