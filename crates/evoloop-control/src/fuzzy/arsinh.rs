//! The synthetic experiment of Section 5.1: the unstable discrete-time plant
//!   x_{k+1} + 1.1 x_k = arsinh(u_k)                                   (eq. 23)
//! is exactly tracked by u_k = sinh(w_k + 1.1 x_k) (eq. 24); a direct fuzzy controller with
//! inputs x'_0 = x_k, x'_1 = w_k and output y'_0 = u_k (the 3 x 3 rule base of Fig. 1, five output
//! MFs, connections I_0(i0, i1) = i0 + i1 of eq. 15) learns that map from the performance measure
//!   G = sum_i |w_i - x_{i+1}|                                          (eq. 25)
//! alone. With |w|, |x| <= 1 the needed |u| reaches sinh(2.1) = 4.02, which is why the paper's
//! optimum has C_y0 = 4.006 and C_x0, C_x1 close to 1.

use super::codec::Codec;
use super::network::{default_labels, FuzzyNetwork, Mf, Variable};

/// The plant's next state.
pub fn plant(x: f64, u: f64) -> f64 {
    -1.1 * x + u.asinh()
}

/// The default desired trajectory (the paper does not print its own): steps between levels in
/// [-1, 1], a ramp and a sine period, 100 samples, so the controller meets the whole input range.
pub fn default_trajectory() -> Vec<f64> {
    let mut w = Vec::with_capacity(100);
    for level in [0.5, -0.5, 1.0, -1.0, 0.0] {
        w.extend(std::iter::repeat_n(level, 10));
    }
    w.extend((0..20).map(|k| -0.8 + 1.6 * k as f64 / 19.0));
    w.extend((0..30).map(|k| 0.9 * (std::f64::consts::TAU * k as f64 / 30.0).sin()));
    w
}

/// The user-specified controller of Fig. 1: N/Z/P at -1/0/1 on both inputs, NG..PG evenly on
/// the output, scaled by `c_y`, widths `w_in` and `w_out`.
pub fn initial_network(c_y: f64, w_in: f64, w_out: f64) -> FuzzyNetwork {
    let var = |name: &str, centres: &[f64], w: f64| Variable {
        name: name.into(),
        labels: default_labels(centres.len()),
        mfs: centres.iter().map(|m| Mf { m: *m, v: w }).collect(),
    };
    let mut rules = Vec::with_capacity(9);
    for i1 in 0..3u16 {
        for i0 in 0..3u16 {
            rules.push(i0 + i1); // eq. 15
        }
    }
    FuzzyNetwork {
        inputs: vec![
            var("x", &[-1.0, 0.0, 1.0], w_in),
            var("w", &[-1.0, 0.0, 1.0], w_in),
        ],
        outputs: vec![var("u", &[-1.0, -0.5, 0.0, 0.5, 1.0], w_out)],
        rules,
        input_scale: vec![1.0, 1.0],
        output_scale: vec![c_y],
        epsilon: 1e-6,
    }
}

/// Genes <-> controller: centres in [-1.25, 1.25] (ordered), widths in [0.1, 1.5], C_x in
/// [0.5, 2], C_y in [1, 8].
pub fn codec() -> Codec {
    Codec {
        template: initial_network(4.0, 0.5, 0.3),
        centre: (-1.25, 1.25),
        width: (0.1, 1.5),
        scale_bounds: vec![(0.5, 2.0), (0.5, 2.0), (1.0, 8.0)],
    }
}

/// The three prespecified sets of the starting population: the Fig. 1 controller as a user
/// writes it down, on normalised ranges with unit scaling (the paper lets "scaling evolve as a
/// by-product"), with narrow, medium and wide membership functions.
pub fn prespecified() -> Vec<FuzzyNetwork> {
    vec![
        initial_network(1.0, 0.4, 0.25),
        initial_network(1.0, 0.5, 0.3),
        initial_network(1.0, 0.6, 0.4),
    ]
}

/// Closed-loop run: x_0 = 0, u_k = controller(x_k, w_k); returns G and optionally the states.
/// A run whose state leaves |x| <= 100 is charged 100 per remaining sample (the plant is
/// unstable; a bad controller must not produce infinities).
pub fn run(net: &FuzzyNetwork, w: &[f64], mut xs: Option<&mut Vec<f64>>) -> f64 {
    let mut x = 0.0;
    let mut g = 0.0;
    let mut u = [0.0];
    if let Some(v) = xs.as_deref_mut() {
        v.push(x);
    }
    for (i, wi) in w.iter().enumerate() {
        net.eval(&[x, *wi], &mut u);
        x = plant(x, u[0]);
        if !x.is_finite() || x.abs() > 100.0 {
            return g + 100.0 * (w.len() - i) as f64;
        }
        g += (wi - x).abs();
        if let Some(v) = xs.as_deref_mut() {
            v.push(x);
        }
    }
    g
}

/// G of the controller the genes describe.
pub struct Objective {
    /// How the genes become the controller that is run.
    pub codec: Codec,
    /// The desired trajectory w_k the closed loop tracks, one value per sample.
    pub trajectory: Vec<f64>,
}

impl crate::optim::Objective for Objective {
    fn value(&self, genes: &[f64]) -> f64 {
        run(&self.codec.decode(genes), &self.trajectory, None)
    }
}
