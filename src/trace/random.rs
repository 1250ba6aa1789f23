//! Random numbers and directions for CPU rays: a keyed PCG32 stream and
//! cosine-weighted hemisphere sampling, shared by the reference path tracer
//! and the solve's contact fix-up, so equal keys give equal rays in both.

use std::f64::consts::TAU;

use glam::DVec3;

/// PCG-XSH-RR 64/32 (O'Neill 2014) with a selectable stream: small, fast and
/// good enough for Monte Carlo integration. Two draws make one `f64`.
#[derive(Clone, Debug)]
pub(crate) struct Rng {
    state: u64,
    increment: u64,
}

const PCG_MULTIPLIER: u64 = 6_364_136_223_846_793_005;

/// SplitMix64's finaliser: a bijective mix of 64 bits.
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    /// A generator whose sequence depends only on `keys` (in order): the
    /// state and the stream are both hashed from them, so different keys give
    /// different, non-overlapping-in-practice sequences.
    pub(crate) fn new(keys: &[u64]) -> Rng {
        let mut h = 0x005E_ED0F_B4CE_u64;
        for &k in keys {
            h = mix64(h ^ mix64(k));
        }
        let mut rng = Rng { state: 0, increment: (mix64(h ^ 0xA5A5_A5A5_A5A5_A5A5) << 1) | 1 };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(h);
        rng.next_u32();
        rng
    }

    pub(crate) fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MULTIPLIER).wrapping_add(self.increment);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub(crate) fn next_f64(&mut self) -> f64 {
        let bits = ((self.next_u32() as u64) << 21) ^ (self.next_u32() as u64 >> 11);
        bits as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// An orthonormal basis around unit `n` (Duff et al., "Building an
/// Orthonormal Basis, Revisited", JCGT 2017): returns (tangent, bitangent).
pub(crate) fn basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), DVec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// A cosine-distributed direction about unit `n` from two uniforms, and its
/// cosine with `n` (the density is cos/π per steradian).
pub(crate) fn cosine_hemisphere(n: DVec3, u1: f64, u2: f64) -> (DVec3, f64) {
    let r = u1.sqrt();
    let phi = TAU * u2;
    let z = (1.0 - u1).max(0.0).sqrt();
    let (t, b) = basis(n);
    let d = (t * (r * phi.cos()) + b * (r * phi.sin()) + n * z).normalize();
    (d, d.dot(n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rng_is_uniform_and_keyed() {
        let mut a = Rng::new(&[1, 2]);
        let mut b = Rng::new(&[1, 3]);
        let xs: Vec<f64> = (0..100_000).map(|_| a.next_f64()).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
        assert!(xs.iter().all(|&x| (0.0..1.0).contains(&x)));
        assert_ne!(Rng::new(&[1, 2]).next_u32(), b.next_u32());
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [DVec3::X, DVec3::NEG_Z, DVec3::new(0.3, -0.4, 0.5).normalize()] {
            let (t, b) = basis(n);
            assert!((t.length() - 1.0).abs() < 1e-12 && (b.length() - 1.0).abs() < 1e-12);
            assert!(t.dot(b).abs() < 1e-12 && t.dot(n).abs() < 1e-12 && b.dot(n).abs() < 1e-12);
        }
    }
}
