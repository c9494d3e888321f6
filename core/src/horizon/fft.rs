//! Complex Fourier transforms of [`LANES`] sequences at once, for the spectrum search of
//! [`super::interference`].
//!
//! That search transforms every row of the working image and then every column of the
//! result: 248 transforms of 128–256 points on a 160 × 120 working image, a quarter of the
//! detector's time on the frames it runs on (`aerial` seeds 137–139 at 320 × 240: 2.5 M of
//! 7.8 M instructions a frame). `microfft` transforms one sequence at a time with scalar
//! arithmetic. Here each butterfly is applied to the same element of eight sequences held
//! side by side ([`Lanes`]), which the compiler turns into vector arithmetic: eight
//! columns of the spectrum at once, or sixteen image rows (two real rows make one complex
//! sequence, [`split_real_pair`]). The arithmetic is the textbook radix-2 decimation in time,
//! with the sign of `microfft` and of most references: `X[k] = Σ x[n]·e^{−2πi·kn/N}`.

/// Sequences transformed together.
pub(crate) const LANES: usize = 8;
/// Longest transform (points).
pub(crate) const MAX_POINTS: usize = 256;

/// One element of [`LANES`] complex sequences.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Lanes {
    pub re: [f32; LANES],
    pub im: [f32; LANES],
}

/// `e^{−2πi·k/MAX_POINTS}` for `k < MAX_POINTS / 2`: a transform of `n` points takes every
/// `MAX_POINTS / n`-th. Built at compile time by rotating in `f64` from the first root (each
/// product's error is about 1e-16: under 1e-13 after 127 of them, far below `f32`'s 6e-8).
const TWIDDLES: [(f32, f32); MAX_POINTS / 2] = {
    // cos and sin of 2π/256.
    let (c, s) = (0.999_698_818_696_204_2_f64, 0.024_541_228_522_912_288_f64);
    let mut table = [(0.0f32, 0.0f32); MAX_POINTS / 2];
    let (mut re, mut im) = (1.0f64, 0.0f64);
    let mut k = 0;
    while k < MAX_POINTS / 2 {
        table[k] = (re as f32, im as f32);
        // Multiply by e^{−2πi/256}.
        let next_re = re * c + im * s;
        im = im * c - re * s;
        re = next_re;
        k += 1;
    }
    table
};

/// Transforms the first `n` elements of `data` in place (`n` a power of two from 2 to
/// [`MAX_POINTS`]); `false`, with `data` untouched, for any other `n` or a `data` shorter
/// than `n`.
pub(crate) fn transform(data: &mut [Lanes], n: usize) -> bool {
    if !n.is_power_of_two() || !(2..=MAX_POINTS).contains(&n) {
        return false;
    }
    let Some(data) = data.get_mut(..n) else {
        return false;
    };
    // Bit-reversed order: the butterflies then combine neighbours, then pairs, and so on.
    let bits = n.trailing_zeros();
    for i in 0..n {
        let j = i.reverse_bits() >> (usize::BITS - bits);
        if i < j {
            data.swap(i, j);
        }
    }
    // The first two stages' twiddles are 1 and −i: additions only.
    for pair in data.chunks_exact_mut(2) {
        if let [a, b] = pair {
            butterfly_by_one(a, b);
        }
    }
    if n >= 4 {
        for quad in data.chunks_exact_mut(4) {
            if let [a0, a1, b0, b1] = quad {
                butterfly_by_one(a0, b0);
                // b1 · (−i) swaps its parts and negates the new imaginary part.
                core::mem::swap(&mut b1.re, &mut b1.im);
                for im in &mut b1.im {
                    *im = -*im;
                }
                butterfly_by_one(a1, b1);
            }
        }
    }
    let mut half = 4;
    while half < n {
        let stride = MAX_POINTS / (2 * half);
        for block in data.chunks_exact_mut(2 * half) {
            let (low, high) = block.split_at_mut(half);
            let twiddles = TWIDDLES.iter().step_by(stride);
            for ((a, b), &(wr, wi)) in low.iter_mut().zip(high.iter_mut()).zip(twiddles) {
                butterfly(a, b, wr, wi);
            }
        }
        half *= 2;
    }
    true
}

/// `a, b ← a + b, a − b`, lane by lane.
#[inline(always)]
fn butterfly_by_one(a: &mut Lanes, b: &mut Lanes) {
    for (x, y) in a.re.iter_mut().zip(b.re.iter_mut()) {
        (*x, *y) = (*x + *y, *x - *y);
    }
    for (x, y) in a.im.iter_mut().zip(b.im.iter_mut()) {
        (*x, *y) = (*x + *y, *x - *y);
    }
}

/// `a, b ← a + w·b, a − w·b`, lane by lane.
#[inline(always)]
fn butterfly(a: &mut Lanes, b: &mut Lanes, wr: f32, wi: f32) {
    let lanes =
        a.re.iter_mut()
            .zip(a.im.iter_mut())
            .zip(b.re.iter_mut().zip(b.im.iter_mut()));
    for ((ar, ai), (br, bi)) in lanes {
        let tr = wr * *br - wi * *bi;
        let ti = wr * *bi + wi * *br;
        *br = *ar - tr;
        *bi = *ai - ti;
        *ar += tr;
        *ai += ti;
    }
}

/// The spectra of two real sequences transformed as one complex sequence (the first as its
/// real part, the second as its imaginary part), at bin `k` of `n`: `Z` is the transform,
/// `Z[k]` given as `z` and `Z[(n − k) mod n]` as `mirror`. Returns `(A[k], B[k])` as
/// `(re, im)` pairs: `A[k] = (Z[k] + conj Z[n−k]) / 2`, `B[k] = (Z[k] − conj Z[n−k]) / 2i`.
#[inline(always)]
pub(crate) fn split_real_pair(z: (f32, f32), mirror: (f32, f32)) -> ((f32, f32), (f32, f32)) {
    let ((zr, zi), (mr, mi)) = (z, mirror);
    (
        (0.5 * (zr + mr), 0.5 * (zi - mi)),
        (0.5 * (zi + mi), 0.5 * (mr - zr)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    /// The transform's angle for bin `k` of `n`.
    fn angle(k: usize, i: usize, n: usize) -> f32 {
        -2.0 * PI * ((k * i) % n) as f32 / n as f32
    }

    /// A repeatable pseudo-random value in [−1, 1).
    fn noise(seed: u32) -> f32 {
        let mut x = seed.wrapping_mul(0x9E37_79B9) ^ 0x5bd1_e995;
        x ^= x >> 15;
        x = x.wrapping_mul(0x2c1b_3c6d);
        x ^= x >> 12;
        (x >> 8) as f32 / (1u32 << 23) as f32 - 1.0
    }

    /// The direct sum `Σ x[i]·e^{−2πi·ki/n}` of lane `l`, in f64.
    fn direct(data: &[Lanes], l: usize, k: usize, n: usize) -> (f64, f64) {
        let mut sum = (0.0f64, 0.0f64);
        for (i, x) in data.iter().take(n).enumerate() {
            let a = f64::from(angle(k, i, n));
            let (c, s) = (libm::cos(a), libm::sin(a));
            let (xr, xi) = (f64::from(x.re[l]), f64::from(x.im[l]));
            sum.0 += xr * c - xi * s;
            sum.1 += xr * s + xi * c;
        }
        sum
    }

    fn random_lanes(n: usize, seed: u32) -> [Lanes; MAX_POINTS] {
        let mut data = [Lanes::default(); MAX_POINTS];
        for (i, x) in data.iter_mut().take(n).enumerate() {
            for l in 0..LANES {
                let at = (seed + (i * LANES + l) as u32) * 2;
                x.re[l] = 100.0 * noise(at);
                x.im[l] = 100.0 * noise(at + 1);
            }
        }
        data
    }

    #[test]
    fn each_lane_is_the_direct_sum_of_its_own_sequence() {
        for n in [2, 4, 16, 128, 256] {
            let input = random_lanes(n, n as u32);
            let mut data = input;
            assert!(transform(&mut data, n));
            // Sums of n values of ±100: the f32 result within 1e-5 of the largest bin.
            let scale = 100.0 * n as f64;
            for l in 0..LANES {
                for k in 0..n {
                    let (re, im) = direct(&input, l, k, n);
                    let got = data.get(k).copied().unwrap_or_default();
                    assert!(
                        (f64::from(got.re[l]) - re).abs() < 1e-5 * scale
                            && (f64::from(got.im[l]) - im).abs() < 1e-5 * scale,
                        "n {n} lane {l} bin {k}: {:?} against ({re}, {im})",
                        (got.re[l], got.im[l])
                    );
                }
            }
        }
    }

    #[test]
    fn lanes_do_not_mix() {
        // Only lane 3 holds a value: every other lane's transform is zero.
        let mut data = [Lanes::default(); 64];
        if let Some(x) = data.get_mut(5) {
            x.re[3] = 1.0;
        }
        assert!(transform(&mut data, 64));
        for x in &data {
            for l in (0..LANES).filter(|&l| l != 3) {
                assert_eq!((x.re[l], x.im[l]), (0.0, 0.0));
            }
            // An impulse at 5: unit magnitude in every bin.
            assert!((libm::hypotf(x.re[3], x.im[3]) - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn other_lengths_are_refused_untouched() {
        let mut data = random_lanes(16, 1);
        let before = data;
        for n in [0, 1, 3, 24, 512] {
            assert!(!transform(&mut data, n), "{n}");
        }
        assert!(!transform(&mut data[..8], 16));
        assert_eq!(data, before);
    }

    #[test]
    fn two_real_sequences_come_apart_from_one_complex_transform() {
        let n = 32;
        let mut data = [Lanes::default(); 32];
        let (a, b): ([f32; 32], [f32; 32]) = (
            core::array::from_fn(|i| noise(i as u32)),
            core::array::from_fn(|i| noise(1000 + i as u32)),
        );
        for (x, (&ai, &bi)) in data.iter_mut().zip(a.iter().zip(&b)) {
            x.re[0] = ai;
            x.im[0] = bi;
        }
        assert!(transform(&mut data, n));
        for k in 0..n {
            let at = |i: usize| {
                let x = data.get(i).copied().unwrap_or_default();
                (x.re[0], x.im[0])
            };
            let (ak, bk) = split_real_pair(at(k), at((n - k) % n));
            let real = |v: &[f32; 32]| {
                let mut one = [Lanes::default(); 32];
                for (x, &vi) in one.iter_mut().zip(v) {
                    x.re[0] = vi;
                }
                direct(&one, 0, k, n)
            };
            for (got, want) in [(ak, real(&a)), (bk, real(&b))] {
                assert!(
                    (f64::from(got.0) - want.0).abs() < 1e-4
                        && (f64::from(got.1) - want.1).abs() < 1e-4,
                    "bin {k}: {got:?} against {want:?}"
                );
            }
        }
    }
}
