//! Number types for the tracer's predicates. Every predicate is written once, generic over [`Num`],
//! and evaluated with f64 carrying a proven running error bound ([`BoundedF64`], the filter), with
//! exact dyadic rationals ([`Dyadic`], the fallback), or with plain f32 ([`PlainF32`], measurement
//! only). All inputs are f32 or f64 values, hence dyadic rationals, and every predicate is a
//! polynomial, so the exact path never divides.

use num_bigint::BigInt;
use num_traits::{Signed, ToPrimitive, Zero};
use std::cmp::Ordering;

/// A number the predicates can be evaluated with.
pub trait Num: Clone + std::fmt::Debug {
    /// Whether `sign` is always certain (exact arithmetic, or a type that never claims certainty).
    const EXACT: bool;
    fn from_f32(x: f32) -> Self;
    /// An f64 constant, taken as the exact dyadic value it denotes.
    fn from_f64(x: f64) -> Self;
    fn add(&self, o: &Self) -> Self;
    fn sub(&self, o: &Self) -> Self;
    fn mul(&self, o: &Self) -> Self;
    fn neg(&self) -> Self;
    /// The sign of the exact value, or `None` when this representation cannot certify it.
    fn sign(&self) -> Option<Ordering>;
    /// An f64 near the value.
    fn approx(&self) -> f64;
    /// A bound on `|approx() - exact value|`.
    fn error(&self) -> f64;
    /// The triple products `d · (a × b)` of two triples of vectors, each as [`triple`] gives it;
    /// a type may evaluate the two side by side.
    #[inline(always)]
    fn triples(pairs: [(&V3<Self>, &V3<Self>, &V3<Self>); 2]) -> [Self; 2]
    where
        Self: Sized,
    {
        let [(d0, a0, b0), (d1, a1, b1)] = pairs;
        [triple(d0, a0, b0), triple(d1, a1, b1)]
    }
}

/// Unit roundoff of f64 (round to nearest).
const U64: f64 = f64::EPSILON / 2.0;

/// Rounds an error bound computed in f64 up past the rounding of its own computation (at most
/// four operations, each off by a factor of at most 1 + u) and past underflow.
#[inline]
fn up(e: f64) -> f64 {
    e * (1.0 + 8.0 * U64) + f64::MIN_POSITIVE
}

/// An f64 value with a proven bound on its distance to the exact value it stands for.
///
/// For each operation on approximations `x̂ = x + δx`, `ŷ = y + δy` (|δx| ≤ ex, |δy| ≤ ey):
/// - `x ± y`: `|fl(x̂ ± ŷ) − (x ± y)| ≤ ex + ey + u·|x̂ ± ŷ|` and `u·|x̂ ± ŷ| ≤ 2u·|fl(x̂ ± ŷ)|`;
/// - `x·y`: `|x̂ŷ − xy| ≤ |x̂|·ey + |ŷ|·ex + ex·ey`, plus the rounding `2u·|fl(x̂ŷ)|`.
///
/// `up` covers the rounding of the bound's own evaluation and underflow. A non-finite value
/// or bound makes `sign` uncertain, so overflow falls back to exact arithmetic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundedF64 {
    pub value: f64,
    pub error: f64,
}

impl Num for BoundedF64 {
    const EXACT: bool = false;
    #[inline]
    fn from_f32(x: f32) -> Self {
        BoundedF64 {
            value: x as f64,
            error: 0.0,
        }
    }
    #[inline]
    fn from_f64(x: f64) -> Self {
        BoundedF64 {
            value: x,
            error: 0.0,
        }
    }
    #[inline]
    fn add(&self, o: &Self) -> Self {
        let value = self.value + o.value;
        BoundedF64 {
            value,
            error: up(self.error + o.error + 2.0 * U64 * value.abs()),
        }
    }
    #[inline]
    fn sub(&self, o: &Self) -> Self {
        let value = self.value - o.value;
        BoundedF64 {
            value,
            error: up(self.error + o.error + 2.0 * U64 * value.abs()),
        }
    }
    #[inline]
    fn mul(&self, o: &Self) -> Self {
        let value = self.value * o.value;
        let error = self.value.abs() * o.error
            + o.value.abs() * self.error
            + self.error * o.error
            + 2.0 * U64 * value.abs();
        BoundedF64 {
            value,
            error: up(error),
        }
    }
    #[inline]
    fn neg(&self) -> Self {
        BoundedF64 {
            value: -self.value,
            error: self.error,
        }
    }
    #[inline]
    fn sign(&self) -> Option<Ordering> {
        if !self.value.is_finite() || !self.error.is_finite() {
            None
        } else if self.value > self.error {
            Some(Ordering::Greater)
        } else if self.value < -self.error {
            Some(Ordering::Less)
        } else if self.value == 0.0 && self.error == 0.0 {
            Some(Ordering::Equal)
        } else {
            None
        }
    }
    fn approx(&self) -> f64 {
        self.value
    }
    fn error(&self) -> f64 {
        self.error
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn triples(pairs: [(&V3<Self>, &V3<Self>, &V3<Self>); 2]) -> [Self; 2] {
        let [(d0, a0, b0), (d1, a1, b1)] = pairs;
        let lanes = |x: &V3<Self>, y: &V3<Self>| map3([0, 1, 2], |k| BoundedPair::of(&x[k], &y[k]));
        BoundedPair::triple(&lanes(d0, d1), &lanes(a0, a1), &lanes(b0, b1)).split()
    }
}

/// Two [`BoundedF64`]s in the two lanes of SSE2 registers (every x86-64 processor has them): each
/// operation is the scalar one's, the same operations in the same order on each lane, so each lane
/// holds bit for bit what [`BoundedF64`] computes (a test compares them on random inputs). Only
/// the arithmetic a triple product needs; it decides no sign.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
struct BoundedPair {
    value: std::arch::x86_64::__m128d,
    error: std::arch::x86_64::__m128d,
}

#[cfg(target_arch = "x86_64")]
impl BoundedPair {
    #[inline(always)]
    fn of(lo: &BoundedF64, hi: &BoundedF64) -> BoundedPair {
        use std::arch::x86_64::_mm_set_pd;
        // SAFETY: SSE2 is part of the x86-64 baseline.
        unsafe {
            BoundedPair {
                value: _mm_set_pd(hi.value, lo.value),
                error: _mm_set_pd(hi.error, lo.error),
            }
        }
    }

    #[inline(always)]
    fn split(self) -> [BoundedF64; 2] {
        let (mut v, mut e) = ([0f64; 2], [0f64; 2]);
        // SAFETY: SSE2 is part of the x86-64 baseline; the stores write two f64 each.
        unsafe {
            std::arch::x86_64::_mm_storeu_pd(v.as_mut_ptr(), self.value);
            std::arch::x86_64::_mm_storeu_pd(e.as_mut_ptr(), self.error);
        }
        [0, 1].map(|k| BoundedF64 {
            value: v[k],
            error: e[k],
        })
    }
}

#[cfg(target_arch = "x86_64")]
mod pair_lanes {
    //! [`BoundedPair`]'s operations: [`BoundedF64`]'s, lane by lane.
    use super::{BoundedPair, U64};
    use std::arch::x86_64::*;

    /// `|x|` on both lanes: the sign bit cleared, as `f64::abs` does.
    #[inline(always)]
    unsafe fn abs(x: __m128d) -> __m128d {
        _mm_andnot_pd(_mm_set1_pd(-0.0), x)
    }

    /// [`super::up`] on both lanes.
    #[inline(always)]
    unsafe fn up(e: __m128d) -> __m128d {
        _mm_add_pd(
            _mm_mul_pd(e, _mm_set1_pd(1.0 + 8.0 * U64)),
            _mm_set1_pd(f64::MIN_POSITIVE),
        )
    }

    impl BoundedPair {
        /// The error of a sum or difference with the value it rounded to.
        #[inline(always)]
        unsafe fn summed(self, o: BoundedPair, value: __m128d) -> BoundedPair {
            let e = _mm_add_pd(
                _mm_add_pd(self.error, o.error),
                _mm_mul_pd(_mm_set1_pd(2.0 * U64), abs(value)),
            );
            BoundedPair {
                value,
                error: up(e),
            }
        }
    }

    impl BoundedPair {
        /// [`super::triple`]: `d · (a × b)` as `dot3` of `cross3`, in their order.
        #[inline(always)]
        pub(super) fn triple(d: &[Self; 3], a: &[Self; 3], b: &[Self; 3]) -> Self {
            let c = [
                a[1].mul(&b[2]).sub(&a[2].mul(&b[1])),
                a[2].mul(&b[0]).sub(&a[0].mul(&b[2])),
                a[0].mul(&b[1]).sub(&a[1].mul(&b[0])),
            ];
            d[0].mul(&c[0]).add(&d[1].mul(&c[1])).add(&d[2].mul(&c[2]))
        }

        #[inline(always)]
        fn add(&self, o: &Self) -> Self {
            // SAFETY: SSE2 is part of the x86-64 baseline.
            unsafe { self.summed(*o, _mm_add_pd(self.value, o.value)) }
        }
        #[inline(always)]
        fn sub(&self, o: &Self) -> Self {
            // SAFETY: SSE2 is part of the x86-64 baseline.
            unsafe { self.summed(*o, _mm_sub_pd(self.value, o.value)) }
        }
        #[inline(always)]
        fn mul(&self, o: &Self) -> Self {
            // SAFETY: SSE2 is part of the x86-64 baseline.
            unsafe {
                let value = _mm_mul_pd(self.value, o.value);
                let e = _mm_add_pd(
                    _mm_add_pd(
                        _mm_add_pd(
                            _mm_mul_pd(abs(self.value), o.error),
                            _mm_mul_pd(abs(o.value), self.error),
                        ),
                        _mm_mul_pd(self.error, o.error),
                    ),
                    _mm_mul_pd(_mm_set1_pd(2.0 * U64), abs(value)),
                );
                BoundedPair {
                    value,
                    error: up(e),
                }
            }
        }
    }
}

/// Plain f32 arithmetic whose signs are taken at face value: what a naive f32 oracle would do.
/// Only for measuring; its classifications carry no guarantee.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlainF32(pub f32);

impl Num for PlainF32 {
    const EXACT: bool = true;
    fn from_f32(x: f32) -> Self {
        PlainF32(x)
    }
    fn from_f64(x: f64) -> Self {
        PlainF32(x as f32)
    }
    fn add(&self, o: &Self) -> Self {
        PlainF32(self.0 + o.0)
    }
    fn sub(&self, o: &Self) -> Self {
        PlainF32(self.0 - o.0)
    }
    fn mul(&self, o: &Self) -> Self {
        PlainF32(self.0 * o.0)
    }
    fn neg(&self) -> Self {
        PlainF32(-self.0)
    }
    fn sign(&self) -> Option<Ordering> {
        Some(self.0.partial_cmp(&0.0).unwrap_or(Ordering::Equal))
    }
    fn approx(&self) -> f64 {
        self.0 as f64
    }
    fn error(&self) -> f64 {
        0.0
    }
}

/// An exact dyadic rational `mantissa · 2^exponent`.
#[derive(Clone, Debug, PartialEq)]
pub struct Dyadic {
    mantissa: BigInt,
    exponent: i64,
}

impl Dyadic {
    pub fn zero() -> Dyadic {
        Dyadic {
            mantissa: BigInt::zero(),
            exponent: 0,
        }
    }

    fn normalised(mut self) -> Dyadic {
        if self.mantissa.is_zero() {
            self.exponent = 0;
            return self;
        }
        let tz = self.mantissa.trailing_zeros().unwrap_or(0);
        if tz > 0 {
            self.mantissa >>= tz;
            self.exponent += tz as i64;
        }
        self
    }

    /// The exact value of a finite f64 (non-finite values are never handed to the predicates).
    pub fn of_f64(x: f64) -> Dyadic {
        if x == 0.0 || !x.is_finite() {
            return Dyadic::zero();
        }
        let bits = x.to_bits();
        let negative = bits >> 63 == 1;
        let biased = ((bits >> 52) & 0x7FF) as i64;
        let fraction = bits & ((1u64 << 52) - 1);
        let (m, e) = if biased == 0 {
            (fraction, -1074)
        } else {
            (fraction | (1u64 << 52), biased - 1075)
        };
        let mantissa = if negative {
            -BigInt::from(m)
        } else {
            BigInt::from(m)
        };
        Dyadic {
            mantissa,
            exponent: e,
        }
        .normalised()
    }

    fn aligned(a: &Dyadic, b: &Dyadic) -> (BigInt, BigInt, i64) {
        let e = a.exponent.min(b.exponent);
        let ma = &a.mantissa << ((a.exponent - e) as usize);
        let mb = &b.mantissa << ((b.exponent - e) as usize);
        (ma, mb, e)
    }
}

impl Num for Dyadic {
    const EXACT: bool = true;
    fn from_f32(x: f32) -> Self {
        Dyadic::of_f64(x as f64)
    }
    fn from_f64(x: f64) -> Self {
        Dyadic::of_f64(x)
    }
    fn add(&self, o: &Self) -> Self {
        if self.mantissa.is_zero() {
            return o.clone();
        }
        if o.mantissa.is_zero() {
            return self.clone();
        }
        let (a, b, e) = Dyadic::aligned(self, o);
        Dyadic {
            mantissa: a + b,
            exponent: e,
        }
        .normalised()
    }
    fn sub(&self, o: &Self) -> Self {
        self.add(&o.neg())
    }
    fn mul(&self, o: &Self) -> Self {
        if self.mantissa.is_zero() || o.mantissa.is_zero() {
            return Dyadic::zero();
        }
        Dyadic {
            mantissa: &self.mantissa * &o.mantissa,
            exponent: self.exponent + o.exponent,
        }
    }
    fn neg(&self) -> Self {
        Dyadic {
            mantissa: -&self.mantissa,
            exponent: self.exponent,
        }
    }
    fn sign(&self) -> Option<Ordering> {
        Some(if self.mantissa.is_zero() {
            Ordering::Equal
        } else if self.mantissa.is_positive() {
            Ordering::Greater
        } else {
            Ordering::Less
        })
    }
    fn approx(&self) -> f64 {
        if self.mantissa.is_zero() {
            return 0.0;
        }
        let bits = self.mantissa.bits() as i64;
        let shift = (bits - 62).max(0);
        let top = (&self.mantissa >> (shift as usize)).to_i64().unwrap_or(0) as f64;
        let mut e = self.exponent + shift;
        let mut v = top;
        // Scale in steps that cannot overflow or underflow an intermediate.
        while e > 0 {
            let s = e.min(1000);
            v *= 2f64.powi(s as i32);
            e -= s;
        }
        while e < 0 {
            let s = (-e).min(1000);
            v /= 2f64.powi(s as i32);
            e += s;
        }
        v
    }
    fn error(&self) -> f64 {
        // Truncation to 62 bits and the scaling steps: a few units in the last place.
        self.approx().abs() * 8.0 * U64 + f64::MIN_POSITIVE
    }
}

/// Three-vectors of a [`Num`].
pub type V3<T> = [T; 3];

#[inline]
pub fn v3<T: Num>(p: [f32; 3]) -> V3<T> {
    [T::from_f32(p[0]), T::from_f32(p[1]), T::from_f32(p[2])]
}

/// `a.map(f)` for three elements, written out so it inlines in the hot paths (the same calls in
/// the same order).
#[inline(always)]
pub(crate) fn map3<T, U>(a: [T; 3], mut f: impl FnMut(T) -> U) -> [U; 3] {
    let [x, y, z] = a;
    [f(x), f(y), f(z)]
}

#[inline]
pub fn sub3<T: Num>(a: &V3<T>, b: &V3<T>) -> V3<T> {
    [a[0].sub(&b[0]), a[1].sub(&b[1]), a[2].sub(&b[2])]
}

#[inline]
pub fn add3<T: Num>(a: &V3<T>, b: &V3<T>) -> V3<T> {
    [a[0].add(&b[0]), a[1].add(&b[1]), a[2].add(&b[2])]
}

#[inline]
pub fn scale3<T: Num>(a: &V3<T>, s: &T) -> V3<T> {
    [a[0].mul(s), a[1].mul(s), a[2].mul(s)]
}

#[inline]
pub fn dot3<T: Num>(a: &V3<T>, b: &V3<T>) -> T {
    a[0].mul(&b[0]).add(&a[1].mul(&b[1])).add(&a[2].mul(&b[2]))
}

#[inline]
pub fn cross3<T: Num>(a: &V3<T>, b: &V3<T>) -> V3<T> {
    [
        a[1].mul(&b[2]).sub(&a[2].mul(&b[1])),
        a[2].mul(&b[0]).sub(&a[0].mul(&b[2])),
        a[0].mul(&b[1]).sub(&a[1].mul(&b[0])),
    ]
}

/// `d · (a × b)`.
#[inline(always)]
pub fn triple<T: Num>(d: &V3<T>, a: &V3<T>, b: &V3<T>) -> T {
    dot3(d, &cross3(a, b))
}

/// `M · p` for a 3x4 affine matrix of f32 entries.
pub fn affine<T: Num>(m: &[[f32; 4]; 3], p: &V3<T>) -> V3<T> {
    [0, 1, 2].map(|r| {
        T::from_f32(m[r][0])
            .mul(&p[0])
            .add(&T::from_f32(m[r][1]).mul(&p[1]))
            .add(&T::from_f32(m[r][2]).mul(&p[2]))
            .add(&T::from_f32(m[r][3]))
    })
}

/// The 3x3 linear part of `m` as numbers.
pub fn linear<T: Num>(m: &[[f32; 4]; 3]) -> [V3<T>; 3] {
    [0, 1, 2].map(|r| [0, 1, 2].map(|c| T::from_f32(m[r][c])))
}

/// The adjugate of a 3x3 matrix (`A · adj(A) = det(A) · I`).
pub fn adjugate<T: Num>(a: &[V3<T>; 3]) -> [V3<T>; 3] {
    let c = |r0: usize, c0: usize, r1: usize, c1: usize| {
        a[r0][c0].mul(&a[r1][c1]).sub(&a[r0][c1].mul(&a[r1][c0]))
    };
    [
        [c(1, 1, 2, 2), c(0, 2, 2, 1), c(0, 1, 1, 2)],
        [c(1, 2, 2, 0), c(0, 0, 2, 2), c(0, 2, 1, 0)],
        [c(1, 0, 2, 1), c(0, 1, 2, 0), c(0, 0, 1, 1)],
    ]
}

pub fn determinant<T: Num>(a: &[V3<T>; 3]) -> T {
    triple(&a[0], &a[1], &a[2])
}

pub fn mat_vec<T: Num>(a: &[V3<T>; 3], v: &V3<T>) -> V3<T> {
    [dot3(&a[0], v), dot3(&a[1], v), dot3(&a[2], v)]
}

/// The exact sign of the determinant of a 3x3 f32 matrix (filter first, exact when needed).
pub fn determinant_sign(m: &[[f32; 4]; 3]) -> Ordering {
    let filtered = determinant(&linear::<BoundedF64>(m)).sign();
    filtered.unwrap_or_else(|| determinant(&linear::<Dyadic>(m)).sign().expect("exact"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dyadic_round_trips_and_cancels_exactly() {
        for x in [
            1.0,
            -3.5,
            1e-300,
            5e-324,
            1.2345678e200,
            f32::MIN_POSITIVE as f64,
        ] {
            assert_eq!(Dyadic::of_f64(x).approx(), x);
        }
        let big = Dyadic::from_f64(1e30);
        let one = Dyadic::from_f64(1.0);
        let s = big.add(&one).sub(&big);
        assert_eq!(s, one);
        assert_eq!(s.sub(&one).sign(), Some(Ordering::Equal));
    }

    /// `BoundedF64::triples` gives each triple product bit for bit as `triple` does, errors
    /// included, on values spread over many magnitudes, with and without input errors.
    #[test]
    fn paired_triples_are_the_scalar_ones_bit_for_bit() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut value = |with_error: bool| {
            let (a, b) = (next(), next());
            let mantissa = (a >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let exponent = (b % 80) as i32 - 40;
            let value = mantissa * 2f64.powi(exponent);
            BoundedF64 {
                value,
                error: if with_error && b % 3 != 0 {
                    value.abs() * 2f64.powi(-40 - (a % 20) as i32)
                } else {
                    0.0
                },
            }
        };
        let mut differing_lanes = 0;
        for round in 0..20_000 {
            let with_error = round % 2 == 1;
            let mut v3 = || [0, 1, 2].map(|_| value(with_error));
            let (d0, a0, b0, d1, a1, b1) = (v3(), v3(), v3(), v3(), v3(), v3());
            let paired = BoundedF64::triples([(&d0, &a0, &b0), (&d1, &a1, &b1)]);
            let scalar = [triple(&d0, &a0, &b0), triple(&d1, &a1, &b1)];
            for (p, s) in paired.iter().zip(&scalar) {
                assert_eq!(p.value.to_bits(), s.value.to_bits(), "{d0:?} {a0:?} {b0:?}");
                assert_eq!(p.error.to_bits(), s.error.to_bits(), "{d0:?} {a0:?} {b0:?}");
            }
            differing_lanes += usize::from(scalar[0].value != scalar[1].value);
        }
        // The two lanes held different inputs.
        assert!(differing_lanes > 19_000);
    }

    #[test]
    fn bounded_f64_refuses_to_certify_cancellation() {
        let big = BoundedF64::from_f64(1e30);
        let one = BoundedF64::from_f64(1.0);
        let s = big.add(&one).sub(&big);
        assert_eq!(s.sign(), None);
        let exact = Dyadic::from_f64(1e30)
            .add(&Dyadic::from_f64(1.0))
            .sub(&Dyadic::from_f64(1e30));
        assert_eq!(exact.sign(), Some(Ordering::Greater));
    }
}
