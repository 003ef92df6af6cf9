#pragma once

// Trigonometry from + - * / only, so synthetic trajectories are bit-identical on every IEEE-754
// platform (libm's sin/cos may differ in the last bit between x86-64 and aarch64, and a pose that
// differs by one ulp renders a few pixels differently). Accuracy ~1e-16 relative on [-pi, pi].

namespace epitrack::synth {

inline constexpr double kPi = 3.14159265358979323846;

namespace detail {
// Reduces x to r in [-pi/4, pi/4] with x = r + q * pi/2 (Cody-Waite, three-part pi/2).
inline double reduceQuarter(double x, long& q) {
  constexpr double kTwoOverPi = 0.63661977236758134308;
  constexpr double kP1 = 1.57079632673412561417e+00;  // fdlibm pio2_1: q * kP1 exact
  constexpr double kP2 = 6.07710050630396597660e-11;  // fdlibm pio2_2
  constexpr double kP3 = 2.02226624879595063154e-21;  // fdlibm pio2_2t
  const double fq = x * kTwoOverPi;
  q = static_cast<long>(fq < 0.0 ? fq - 0.5 : fq + 0.5);
  const double dq = static_cast<double>(q);
  return ((x - dq * kP1) - dq * kP2) - dq * kP3;
}
inline double sinPoly(double r) {  // Taylor to r^17 on |r| <= pi/4
  const double r2 = r * r;
  double s = 1.0 / 355687428096000.0;  // 1/17!
  s = s * r2 - 1.0 / 1307674368000.0;
  s = s * r2 + 1.0 / 6227020800.0;
  s = s * r2 - 1.0 / 39916800.0;
  s = s * r2 + 1.0 / 362880.0;
  s = s * r2 - 1.0 / 5040.0;
  s = s * r2 + 1.0 / 120.0;
  s = s * r2 - 1.0 / 6.0;
  return r + r * r2 * s;
}
inline double cosPoly(double r) {  // Taylor to r^18
  const double r2 = r * r;
  double c = 1.0 / 6402373705728000.0;  // 1/18!
  c = c * r2 - 1.0 / 20922789888000.0;
  c = c * r2 + 1.0 / 87178291200.0;
  c = c * r2 - 1.0 / 479001600.0;
  c = c * r2 + 1.0 / 3628800.0;
  c = c * r2 - 1.0 / 40320.0;
  c = c * r2 + 1.0 / 720.0;
  c = c * r2 - 1.0 / 24.0;
  c = c * r2 + 0.5;
  return 1.0 - r2 * c;
}
}  // namespace detail

inline double portableSin(double x) {
  long q = 0;
  const double r = detail::reduceQuarter(x, q);
  switch (q & 3) {
    case 0:
      return detail::sinPoly(r);
    case 1:
      return detail::cosPoly(r);
    case 2:
      return -detail::sinPoly(r);
    default:
      return -detail::cosPoly(r);
  }
}

inline double portableCos(double x) {
  long q = 0;
  const double r = detail::reduceQuarter(x, q);
  switch (q & 3) {
    case 0:
      return detail::cosPoly(r);
    case 1:
      return -detail::sinPoly(r);
    case 2:
      return -detail::cosPoly(r);
    default:
      return detail::sinPoly(r);
  }
}

inline double degToRad(double deg) { return deg * (kPi / 180.0); }

}  // namespace epitrack::synth
