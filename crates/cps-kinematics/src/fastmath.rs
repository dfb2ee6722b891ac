//! Sine and cosine of a batch of joint angles, written so that the compiler vectorises
//! them: forward kinematics of a 7-joint arm spends half its time in seven scalar libm
//! `sin_cos` calls otherwise.
//!
//! Method (the classic fdlibm design, implemented here from its published constants):
//! reduce `x = k·π/2 + r` with `|r| ≤ π/4` by a three-part Cody-Waite split of π/2 (exact
//! for `|k| < 2^20`), evaluate the degree-13 sine and degree-14 cosine minimax polynomials
//! on `r`, and pick and sign them by the quadrant `k mod 4` without branches. Accurate to
//! about 1 ulp; arguments with `|x| > 1e5` (never a joint angle) or non-finite ones fall
//! back to the standard library.

/// π/2 in three parts of 33 bits each (fdlibm's `pio2_1`, `pio2_2`, `pio2_3`).
const PIO2_1: f64 = 1.570_796_326_734_125_6;
const PIO2_2: f64 = 6.077_100_506_303_966e-11;
const PIO2_3: f64 = 2.022_266_248_711_166_5e-21;
const TWO_OVER_PI: f64 = std::f64::consts::FRAC_2_PI;
/// 1.5 · 2^52: adding and subtracting it rounds to the nearest integer, and the low bits of
/// the sum hold that integer.
const ROUNDER: f64 = 6_755_399_441_055_744.0;

const S: [f64; 6] = [
    -1.666_666_666_666_663_2e-1,
    8.333_333_333_322_49e-3,
    -1.984_126_982_985_795e-4,
    2.755_731_370_707_007e-6,
    -2.505_076_025_340_686_3e-8,
    1.589_690_995_211_55e-10,
];
const C: [f64; 6] = [
    4.166_666_666_666_66e-2,
    -1.388_888_888_887_411e-3,
    2.480_158_728_947_673e-5,
    -2.755_731_435_139_066_3e-7,
    2.087_572_321_298_175e-9,
    -1.135_964_755_778_819_5e-11,
];

/// `a·b + c`, fused when the caller was compiled for FMA.
#[inline(always)]
fn fma<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

/// `c₀ + z (c₁ + z (… + z c₅))`.
#[inline(always)]
fn horner<const FMA: bool>(z: f64, c: &[f64; 6]) -> f64 {
    let mut p = c[5];
    for &ci in c[..5].iter().rev() {
        p = fma::<FMA>(z, p, ci);
    }
    p
}

#[inline(always)]
fn kernel<const FMA: bool>(x: f64) -> (f64, f64) {
    let t = fma::<FMA>(x, TWO_OVER_PI, ROUNDER);
    let quadrant = t.to_bits() as u32; // low bits of the rounded k (two's complement)
    let k = t - ROUNDER;
    // k·PIO2_1 is exact (33-bit parts), so the reduction loses nothing.
    let r = fma::<FMA>(
        -k,
        PIO2_3,
        fma::<FMA>(-k, PIO2_2, fma::<FMA>(-k, PIO2_1, x)),
    );
    let z = r * r;
    let s = fma::<FMA>(r * z, horner::<FMA>(z, &S), r);
    let c = fma::<FMA>(z * z, horner::<FMA>(z, &C), fma::<FMA>(-0.5, z, 1.0));
    let swap = quadrant & 1 == 1;
    let (sin, cos) = if swap { (c, s) } else { (s, c) };
    let sin_sign = u64::from(quadrant & 2 != 0) << 63;
    let cos_sign = u64::from(quadrant.wrapping_add(1) & 2 != 0) << 63;
    (
        f64::from_bits(sin.to_bits() ^ sin_sign),
        f64::from_bits(cos.to_bits() ^ cos_sign),
    )
}

/// Lanes processed together; a multiple of every SIMD width, so blocks vectorise.
const BLOCK: usize = 8;

/// Writes `sin xᵢ` and `cos xᵢ` for every `xᵢ` of `x` into `sin` and `cos`.
///
/// # Panics
/// If `sin` or `cos` is shorter than `x`.
#[inline(always)]
pub(crate) fn sin_cos_batch<const FMA: bool>(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    let (sin, cos) = (&mut sin[..x.len()], &mut cos[..x.len()]);
    if !x.iter().all(|v| v.abs() <= 1e5) {
        for ((s, c), &v) in sin.iter_mut().zip(cos.iter_mut()).zip(x) {
            (*s, *c) = v.sin_cos();
        }
        return;
    }
    for ((xs, ss), cs) in x
        .chunks(BLOCK)
        .zip(sin.chunks_mut(BLOCK))
        .zip(cos.chunks_mut(BLOCK))
    {
        let mut block = [0.0; BLOCK];
        block[..xs.len()].copy_from_slice(xs);
        let (mut bs, mut bc) = ([0.0; BLOCK], [0.0; BLOCK]);
        for i in 0..BLOCK {
            (bs[i], bc[i]) = kernel::<FMA>(block[i]);
        }
        ss.copy_from_slice(&bs[..xs.len()]);
        cs.copy_from_slice(&bc[..xs.len()]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn ulps(a: f64, b: f64) -> f64 {
        // error in units of the last place of the larger magnitude (at least 2^-53 near 0)
        let scale = a.abs().max(b.abs()).max(f64::MIN_POSITIVE);
        (a - b).abs() / (scale * f64::EPSILON)
    }

    #[test]
    fn agrees_with_libm_to_two_ulp_or_1e_16_absolute() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut x: Vec<f64> = (0..200_000)
            .map(|_| rng.random_range(-20.0..20.0))
            .collect();
        x.extend((-64..=64).map(|k| k as f64 * std::f64::consts::FRAC_PI_4));
        x.extend([0.0, -0.0, 1e-300, 1e-8, -1e-8, 99_999.0, -99_999.9]);
        let n = x.len();
        let (mut s, mut c) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
        sin_cos_batch::<false>(&x, &mut s[..n], &mut c[..n]);
        sin_cos_batch::<true>(&x, &mut s[n..], &mut c[n..]);
        x.extend(x.clone());
        for (&v, (&s, &c)) in x.iter().zip(s.iter().zip(&c)) {
            let (s0, c0) = v.sin_cos();
            for (got, want, what) in [(s, s0, "sin"), (c, c0, "cos")] {
                assert!(
                    ulps(got, want) <= 2.0 || (got - want).abs() <= 1.2e-16,
                    "{what}({v}) = {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn large_and_non_finite_arguments_fall_back() {
        let x = [0.5, 1e6, f64::NAN];
        let (mut s, mut c) = ([0.0; 3], [0.0; 3]);
        sin_cos_batch::<true>(&x, &mut s, &mut c);
        assert_eq!((s[1], c[1]), 1e6f64.sin_cos());
        assert!(s[2].is_nan());
    }
}
