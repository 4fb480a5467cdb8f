// Implicit Gauss–Legendre Runge–Kutta collocation with s stages (order 2s, A-stable,
// symplectic), written once for any scalar type T (double, long double): the integrator of
// the extended-precision references (extended_reference.hpp).
//
// Coefficients computed in T at construction, no printed tables: the nodes are the roots of
// the Legendre polynomial P_s on [−1, 1] (Newton from Tricomi's start cos(π(i − 1/4)/(s + 1/2))),
// mapped to c_i = (1 + x_i)/2; the weights b_i = 1/((1 − x_i²) P_s′(x_i)²); the collocation
// matrix a_ij = ∫_0^{c_i} ℓ_j from the Vandermonde conditions Σ_j a_ij c_j^{k−1} = c_i^k / k,
// k = 1…s (Hairer, Nørsett & Wanner I, §II.7).
//
// One step of size h from (t, y): the stage increments Z_i = h Σ_j a_ij f(t + c_j h, y + Z_j)
// by simplified Newton, (I − h A ⊗ J) ΔZ = −(Z − h (A ⊗ I) F(Z)), J = ∂f/∂y at (t, y) by
// central differences in T, until the update is below 2 ε_T relative to |y_k| + |Z_k| in
// every component (or stops halving below 1e3 ε_T: round-off level); then y⁺ = y + h Σ_i b_i f(t + c_i h, y + Z_i).
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

namespace kneedyn {
namespace bench {

template <typename T>
class GaussLegendre {
 public:
  using Vector = Eigen::Matrix<T, Eigen::Dynamic, 1>;
  using Matrix = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  // ydot = f(t, y); may throw (the step is then abandoned by the caller).
  using Rhs = std::function<void(const T& t, const Vector& y, Vector* ydot)>;

  struct Counters {
    long steps = 0;
    long rhs_evaluations = 0;
    long jacobians = 0;
    long newton_iterations = 0;
  };

  explicit GaussLegendre(int stages) : s_(stages), c_(stages), b_(stages), a_(stages, stages) {
    using std::abs;  // std:: for the builtin types, argument-dependent lookup for others
    using std::acos;
    using std::cos;
    const T pi = acos(T(-1));
    for (int i = 0; i < s_; ++i) {
      T x = cos(pi * (T(i) + T(0.75)) / (T(s_) + T(0.5)));
      T dp = 0;
      for (int iter = 0; iter < 100; ++iter) {
        T p, d;
        Legendre(x, &p, &d);
        const T dx = p / d;
        x -= dx;
        dp = d;
        if (abs(dx) <= 4 * std::numeric_limits<T>::epsilon()) break;
      }
      T p, d;
      Legendre(x, &p, &d);
      dp = d;
      c_(i) = (T(1) + x) / T(2);
      b_(i) = T(1) / ((T(1) - x * x) * dp * dp);
    }
    Matrix V(s_, s_);  // V(k, j) = c_j^k
    Matrix R(s_, s_);  // R(k, i) = c_i^{k+1} / (k + 1)
    for (int j = 0; j < s_; ++j) {
      T power = 1;
      for (int k = 0; k < s_; ++k) {
        V(k, j) = power;
        power *= c_(j);
        R(k, j) = power / T(k + 1);
      }
    }
    a_ = V.fullPivLu().solve(R).transpose();  // Σ_j a_ij c_j^k = c_i^{k+1}/(k+1)
  }

  int stages() const { return s_; }
  const Vector& nodes() const { return c_; }
  const Vector& weights() const { return b_; }
  const Matrix& matrix() const { return a_; }
  const Counters& counters() const { return counters_; }

  // One step; false when Newton does not converge in 60 iterations.
  bool Step(const Rhs& f, const T& t, const Vector& y, const T& h, Vector* y_next) {
    using std::abs;
    const int n = static_cast<int>(y.size());
    const int N = s_ * n;
    Vector f0(n);
    f(t, y, &f0);
    ++counters_.rhs_evaluations;
    const Matrix J = Jacobian(f, t, y);
    Matrix W = Matrix::Identity(N, N);
    for (int i = 0; i < s_; ++i) {
      for (int j = 0; j < s_; ++j) W.block(i * n, j * n, n, n) -= h * a_(i, j) * J;
    }
    const Eigen::PartialPivLU<Matrix> lu(W);
    Vector Z(N);  // start: Z_i = c_i h f(t, y)
    for (int i = 0; i < s_; ++i) Z.segment(i * n, n) = c_(i) * h * f0;
    Vector F(N), stage(n), fi(n);
    const T eps = std::numeric_limits<T>::epsilon();
    T previous = std::numeric_limits<T>::infinity();
    bool converged = false;
    for (int iter = 0; iter < 60; ++iter) {
      Evaluate(f, t, y, h, Z, &F);
      Vector residual(N);
      for (int i = 0; i < s_; ++i) {
        Vector sum = Vector::Zero(n);
        for (int j = 0; j < s_; ++j) sum += a_(i, j) * F.segment(j * n, n);
        residual.segment(i * n, n) = Z.segment(i * n, n) - h * sum;
      }
      const Vector dZ = lu.solve(-residual);
      Z += dZ;
      ++counters_.newton_iterations;
      // Update relative to each component's own size (|y_k| + |Z_k|; small velocities
      // must converge as far as large positions).
      T size = 0;
      for (int k = 0; k < N; ++k) {
        const T scale = abs(y(k % n)) + abs(Z(k)) + std::numeric_limits<T>::min();
        size = std::max(size, T(abs(dZ(k)) / scale));
      }
      // Converged at round-off: the update is below 2 ε, or below 1e3 ε and no longer halving.
      if (size <= 2 * eps || (size <= 1000 * eps && size >= previous / 2)) {
        converged = true;
        break;
      }
      previous = size;
    }
    if (!converged) return false;
    Evaluate(f, t, y, h, Z, &F);
    Vector increment = Vector::Zero(n);
    for (int i = 0; i < s_; ++i) increment += b_(i) * F.segment(i * n, n);
    *y_next = y + h * increment;
    ++counters_.steps;
    return true;
  }

 private:
  // P_s(x) and P_s'(x) by the three-term recurrence.
  void Legendre(const T& x, T* p, T* dp) const {
    T p0 = 1, p1 = x;
    for (int k = 2; k <= s_; ++k) {
      const T p2 = (T(2 * k - 1) * x * p1 - T(k - 1) * p0) / T(k);
      p0 = p1;
      p1 = p2;
    }
    *p = s_ == 0 ? T(1) : p1;
    *dp = T(s_) * (x * p1 - p0) / (x * x - T(1));
  }

  void Evaluate(const Rhs& f, const T& t, const Vector& y, const T& h, const Vector& Z, Vector* F) {
    const int n = static_cast<int>(y.size());
    Vector stage(n), fi(n);
    for (int i = 0; i < s_; ++i) {
      stage = y + Z.segment(i * n, n);
      f(t + c_(i) * h, stage, &fi);
      F->segment(i * n, n) = fi;
      ++counters_.rhs_evaluations;
    }
  }

  // ∂f/∂y by central differences with steps ε^(1/3) (|y_k| + 1): only the Newton matrix.
  Matrix Jacobian(const Rhs& f, const T& t, const Vector& y) {
    using std::abs;
    using std::cbrt;
    const int n = static_cast<int>(y.size());
    Matrix J(n, n);
    // Sized by the int n: copies sized by y.size() draw GCC 12's false -Wstringop-overflow
    // from float128's zero fill.
    Vector yp = y.head(n), ym = y.head(n), fp(n), fm(n);
    const T step = cbrt(std::numeric_limits<T>::epsilon());
    for (int k = 0; k < n; ++k) {
      const T dk = step * (abs(y(k)) + T(1));
      yp(k) = y(k) + dk;
      ym(k) = y(k) - dk;
      f(t, yp, &fp);
      f(t, ym, &fm);
      J.col(k) = (fp - fm) / (2 * dk);
      yp(k) = y(k);
      ym(k) = y(k);
    }
    counters_.rhs_evaluations += 2 * n;
    ++counters_.jacobians;
    return J;
  }

  int s_;
  Vector c_, b_;
  Matrix a_;
  Counters counters_;
};

}  // namespace bench
}  // namespace kneedyn
