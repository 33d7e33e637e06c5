//! Four points at a time (module doc, speed): the [`Lanes`] of the fit's
//! passes, portable ([`F4`]) and AVX2 ([`Y4`]), and the per-point terms
//! built on them.

use super::types::Circle;

/// Points per step of the passes over the points. Every quantity of a step
/// holds four points' values ([`Lanes`]), and the sums are kept per lane and
/// added in a fixed order at the end.
pub(super) const LANES: usize = 4;

/// Four `f64` lanes and the operations the fit's passes need, each the same
/// IEEE operation on every lane (no fused multiply-add), so that the two
/// implementations, [`F4`] (portable) and [`Y4`] (AVX2, one instruction per
/// operation), give the same bits (tested).
pub(super) trait Lanes:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
    + std::ops::AddAssign
{
    const ZERO: Self;
    fn splat(v: f64) -> Self;
    /// The first four values of `v`.
    fn load(v: &[f64]) -> Self;
    /// Into the first four values of `out`.
    fn store(self, out: &mut [f64]);
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    /// `max(self, o)`; `o` where `self` is NaN.
    fn max(self, o: Self) -> Self;
    /// `self` where `a < b`, 0 elsewhere (also where either is NaN).
    fn where_lt(self, a: Self, b: Self) -> Self;
    /// `self` where `a ≤ b`, 0 elsewhere (also where either is NaN).
    fn where_le(self, a: Self, b: Self) -> Self;
    /// The sum of the lanes, `(l₀ + l₁) + (l₂ + l₃)`.
    fn total(self) -> f64;
}

/// Portable [`Lanes`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct F4([f64; LANES]);

impl F4 {
    #[inline(always)]
    fn zip(self, o: F4, f: impl Fn(f64, f64) -> f64) -> F4 {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = f(self.0[l], o.0[l]);
        }
        F4(r)
    }
}

impl Lanes for F4 {
    const ZERO: F4 = F4([0.0; LANES]);

    #[inline(always)]
    fn splat(v: f64) -> F4 {
        F4([v; LANES])
    }

    #[inline(always)]
    fn load(v: &[f64]) -> F4 {
        F4([v[0], v[1], v[2], v[3]])
    }

    #[inline(always)]
    fn store(self, out: &mut [f64]) {
        out[..LANES].copy_from_slice(&self.0);
    }

    #[inline(always)]
    fn sqrt(self) -> F4 {
        F4(self.0.map(f64::sqrt))
    }

    #[inline(always)]
    fn abs(self) -> F4 {
        F4(self.0.map(f64::abs))
    }

    #[inline(always)]
    fn max(self, o: F4) -> F4 {
        self.zip(o, |a, b| if a > b { a } else { b })
    }

    #[inline(always)]
    fn where_lt(self, a: F4, b: F4) -> F4 {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = if a.0[l] < b.0[l] { self.0[l] } else { 0.0 };
        }
        F4(r)
    }

    #[inline(always)]
    fn where_le(self, a: F4, b: F4) -> F4 {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = if a.0[l] <= b.0[l] { self.0[l] } else { 0.0 };
        }
        F4(r)
    }

    #[inline(always)]
    fn total(self) -> f64 {
        (self.0[0] + self.0[1]) + (self.0[2] + self.0[3])
    }
}

macro_rules! f4_ops {
    ($($op:ident $f:ident $sym:tt),*) => {$(
        impl std::ops::$op for F4 {
            type Output = F4;
            #[inline(always)]
            fn $f(self, o: F4) -> F4 {
                self.zip(o, |a, b| a $sym b)
            }
        }
    )*};
}
f4_ops!(Add add +, Sub sub -, Mul mul *, Div div /);

impl std::ops::Neg for F4 {
    type Output = F4;
    #[inline(always)]
    fn neg(self) -> F4 {
        F4(self.0.map(|a| -a))
    }
}

impl std::ops::AddAssign for F4 {
    #[inline(always)]
    fn add_assign(&mut self, o: F4) {
        *self = *self + o;
    }
}

/// [`Lanes`] in one AVX2 register. Only used inside [`fit_circle_avx2`],
/// which runs only on CPUs with AVX2: that is what makes its intrinsics
/// sound.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct Y4(std::arch::x86_64::__m256d);

#[cfg(target_arch = "x86_64")]
mod y4 {
    use super::{Lanes, LANES, Y4};
    use std::arch::x86_64::*;

    // SAFETY (every block below): AVX2 is present (see `Y4`); loads and
    // stores touch the first LANES values of slices checked to hold them.
    impl Lanes for Y4 {
        const ZERO: Y4 = Y4(unsafe { std::mem::transmute::<[f64; LANES], __m256d>([0.0; LANES]) });

        #[inline(always)]
        fn splat(v: f64) -> Y4 {
            Y4(unsafe { _mm256_set1_pd(v) })
        }

        #[inline(always)]
        fn load(v: &[f64]) -> Y4 {
            let v = &v[..LANES];
            Y4(unsafe { _mm256_loadu_pd(v.as_ptr()) })
        }

        #[inline(always)]
        fn store(self, out: &mut [f64]) {
            let out = &mut out[..LANES];
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), self.0) }
        }

        #[inline(always)]
        fn sqrt(self) -> Y4 {
            Y4(unsafe { _mm256_sqrt_pd(self.0) })
        }

        #[inline(always)]
        fn abs(self) -> Y4 {
            Y4(unsafe { _mm256_andnot_pd(_mm256_set1_pd(-0.0), self.0) })
        }

        #[inline(always)]
        fn max(self, o: Y4) -> Y4 {
            // maxpd gives its second operand where either is NaN; with the
            // operands swapped that is `self` where `o` is NaN, matching
            // `if a > b { a } else { b }` lane by lane.
            Y4(unsafe { _mm256_max_pd(o.0, self.0) })
        }

        #[inline(always)]
        fn where_lt(self, a: Y4, b: Y4) -> Y4 {
            Y4(unsafe { _mm256_and_pd(self.0, _mm256_cmp_pd::<_CMP_LT_OQ>(a.0, b.0)) })
        }

        #[inline(always)]
        fn where_le(self, a: Y4, b: Y4) -> Y4 {
            Y4(unsafe { _mm256_and_pd(self.0, _mm256_cmp_pd::<_CMP_LE_OQ>(a.0, b.0)) })
        }

        #[inline(always)]
        fn total(self) -> f64 {
            // A plain bit copy, no intrinsic (so it inlines anywhere).
            let l = unsafe { std::mem::transmute::<__m256d, [f64; LANES]>(self.0) };
            (l[0] + l[1]) + (l[2] + l[3])
        }
    }

    macro_rules! y4_ops {
        ($($op:ident $f:ident $intr:ident),*) => {$(
            impl std::ops::$op for Y4 {
                type Output = Y4;
                #[inline(always)]
                fn $f(self, o: Y4) -> Y4 {
                    Y4(unsafe { $intr(self.0, o.0) })
                }
            }
        )*};
    }
    y4_ops!(Add add _mm256_add_pd, Sub sub _mm256_sub_pd, Mul mul _mm256_mul_pd, Div div _mm256_div_pd);

    impl std::ops::Neg for Y4 {
        type Output = Y4;
        #[inline(always)]
        fn neg(self) -> Y4 {
            Y4(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
    }

    impl std::ops::AddAssign for Y4 {
        #[inline(always)]
        fn add_assign(&mut self, o: Y4) {
            *self = *self + o;
        }
    }
}

/// Four points' residuals `ρ − r` at distances `ρ` from the centre and their
/// unit vectors `(dx, dz)/ρ` (`(0, 0)` at `ρ = 0`): a square root and a
/// division per point, the costliest operations of a pass.
#[inline(always)]
pub(super) fn geometry<V: Lanes>(x: V, z: V, c: &Circle) -> (V, V, V) {
    let (dx, dz) = (x - V::splat(c.x_px), z - V::splat(c.z_px));
    let rho = (dx * dx + dz * dz).sqrt();
    let inv = (V::splat(1.0) / rho).where_lt(V::ZERO, rho);
    (rho - V::splat(c.r_px), dx * inv, dz * inv)
}

/// The normal equations' sums of four points (`j = (−uₓ, −u_z, −1)`):
/// `JᵀWd`, then the lower triangle of `JᵀWJ`, `(x x), (z x), (z z), (r x),
/// (r z), (r r)`.
#[inline(always)]
pub(super) fn normal_terms<V: Lanes>(w: V, ux: V, uz: V, d: V) -> [V; 9] {
    let (wx, wz) = (w * ux, w * uz);
    [
        -(wx * d),
        -(wz * d),
        -(w * d),
        wx * ux,
        wz * ux,
        wz * uz,
        wx,
        wz,
        w,
    ]
}

/// `(JᵀWJ, JᵀWd)` from the sums of [`normal_terms`], with a tiny Levenberg
/// damping of 1e-9 on the diagonal.
pub(super) fn normal_matrix<V: Lanes>(sums: [V; 9]) -> ([[f64; 3]; 3], [f64; 3]) {
    let t = sums.map(V::total);
    let d = 1.0 + 1e-9;
    (
        [
            [t[3] * d, t[4], t[6]],
            [t[4], t[5] * d, t[7]],
            [t[6], t[7], t[8] * d],
        ],
        [t[0], t[1], t[2]],
    )
}
