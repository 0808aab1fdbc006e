//! Fuzzy membership selection among identified models (RKGNN paper, Section 5.2, eqs. 17-20).
//!
//! Each model i was identified on a training trajectory; its premise at sample k is that
//! trajectory's z_i(k) = [theta_i; theta_i'] (eq. 17), the new reference's is z_r(k) (eq. 18).
//! The grade of membership of z_r in model i's fuzzy set for premise j is a Gaussian (eq. 19),
//! the model's weight the product over the p premises (eq. 20), and the paper's rule takes the
//! model of largest weight (`Selection::Max`); `Selection::Blend` (beyond the paper) weights the
//! models by their normalised memberships, and `Selection::Evidence` (beyond the paper too)
//! weights them per joint by how well each explains the measured motion under the applied
//! torque, against a uniform prior or the memberships (`law::evidence`).
//!
//! Reading of eq. 19. As printed, M_ij = exp(ln(0.5) (z_ij - z_rj)^2 gamma L_j^2) multiplies the
//! squared distance by gamma L_j^2: trajectories further apart (larger L_j) would give *narrower*
//! sets, and gamma, "a constant that governs the width of fuzzy sets", would narrow them as it
//! grows. We read it as the usual half-width form
//!   M_ij = exp(ln(0.5) ((z_ij - z_rj) / (gamma L_j))^2),
//! under which the membership is exactly 1/2 at a distance gamma L_j (0.66 of the way to the
//! adjacent trajectory, with the paper's gamma), so between two trajectories the nearer one
//! always wins and both sets overlap. L_j is the distance between premise j of the two adjacent
//! training trajectories; it must be positive (the caller supplies a floor where they cross).

/// How the selector turns weights into a law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Selection {
    /// The paper's rule: the model of largest weight w_i (eq. 20).
    Max,
    /// Every model, weighted by w_i / sum w.
    Blend,
    /// Every model, weighted per joint by its evidence (`law::evidence`) against a prior:
    /// uniform, or the memberships' w_i / sum w.
    Evidence,
}

/// The paper's gamma.
pub const GAMMA: f64 = 0.66;

/// Eq. 19 (read as above): the grade of membership of `z_r` in the set centred on `z_i`,
/// half-width `gamma * l` (> 0).
pub fn membership(z_i: f64, z_r: f64, l: f64, gamma: f64) -> f64 {
    let s = (z_i - z_r) / (gamma * l);
    (std::f64::consts::LN_2 * -(s * s)).exp()
}

/// Eq. 20: w_i = prod_j M_ij, for each model's premise vector `centres[i]` against `z_r`, with
/// per-premise distances `l`; written into `w` (one per model). Allocation-free.
pub fn weights(centres: &[&[f64]], z_r: &[f64], l: &[f64], gamma: f64, w: &mut [f64]) {
    for (wi, zi) in w.iter_mut().zip(centres) {
        *wi = zi
            .iter()
            .zip(z_r)
            .zip(l)
            .map(|((a, b), lj)| membership(*a, *b, *lj, gamma))
            .product();
    }
}

/// The index of the largest weight (the first of equals).
pub fn largest<T: PartialOrd>(w: &[T]) -> usize {
    w.iter()
        .enumerate()
        .fold(0, |b, (i, v)| if *v > w[b] { i } else { b })
}

/// The rule: with `Max`, 1 for the first model of largest weight and 0 for the others; with
/// `Blend` and `Evidence` (the memberships as its prior), the weights normalised to sum 1
/// (uniform if every weight underflows to 0). In place.
pub fn select(selection: Selection, w: &mut [f64]) {
    match selection {
        Selection::Max => {
            let best = largest(w);
            for (i, v) in w.iter_mut().enumerate() {
                *v = if i == best { 1.0 } else { 0.0 };
            }
        }
        Selection::Blend | Selection::Evidence => {
            let sum: f64 = w.iter().sum();
            let n = w.len() as f64;
            for v in w.iter_mut() {
                *v = if sum > 0.0 { *v / sum } else { 1.0 / n };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq_19_by_hand() {
        // On the centre: 1. At gamma L: 1/2. At 2 gamma L: 1/16. Symmetric.
        assert_eq!(membership(0.3, 0.3, 0.5, GAMMA), 1.0);
        let at = |d: f64| membership(1.0, 1.0 + d, 0.5, GAMMA);
        assert!((at(0.33) - 0.5).abs() < 1e-15);
        assert!((at(-0.33) - 0.5).abs() < 1e-15);
        assert!((at(0.66) - 0.0625).abs() < 1e-15);
        // Hand value: d = 0.1, gamma L = 0.33: exp(-ln2 (0.1/0.33)^2) = 0.938333...
        assert!(
            (at(0.1) - 0.938_333_472_429_211).abs() < 1e-12,
            "{}",
            at(0.1)
        );
    }

    #[test]
    fn eq_20_and_the_rules_by_hand() {
        // Two models, two premises, L = [1, 2], gamma 0.5: half-widths 0.5 and 1.
        let (m1, m2) = ([0.0, 0.0], [1.0, 2.0]);
        let z_r = [0.5, 0.5];
        let mut w = [0.0; 2];
        weights(&[&m1, &m2], &z_r, &[1.0, 2.0], 0.5, &mut w);
        // Model 1: M = 1/2 (0.5 of 0.5) times 2^-(0.25) (0.5 of 1) = 0.42045...
        // Model 2: M = 1/2 times 2^-(2.25) (1.5 of 1) = 0.10511...
        let w1 = 0.5 * 2f64.powf(-0.25);
        let w2 = 0.5 * 2f64.powf(-2.25);
        assert!(
            (w[0] - w1).abs() < 1e-15 && (w[1] - w2).abs() < 1e-15,
            "{w:?}"
        );
        let mut max = w;
        select(Selection::Max, &mut max);
        assert_eq!(max, [1.0, 0.0]);
        let mut blend = w;
        select(Selection::Blend, &mut blend);
        assert!((blend[0] - w1 / (w1 + w2)).abs() < 1e-15);
        assert!((blend[0] + blend[1] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn between_two_trajectories_the_nearer_model_wins() {
        // One premise, trajectories at 0 and L = 1: the reference at x in (0, 1) picks model 1
        // iff x < 1/2, and the two memberships cross at 1/2.
        for k in 1..100 {
            let x = k as f64 / 100.0;
            let mut w = [0.0; 2];
            weights(&[&[0.0], &[1.0]], &[x], &[1.0], GAMMA, &mut w);
            select(Selection::Max, &mut w);
            assert_eq!(w[0] == 1.0, x <= 0.5, "x = {x}");
        }
    }

    #[test]
    fn a_blend_of_vanishing_weights_is_uniform_not_nan() {
        let mut w = [0.0, 0.0, 0.0];
        select(Selection::Blend, &mut w);
        assert_eq!(w, [1.0 / 3.0; 3]);
    }
}
