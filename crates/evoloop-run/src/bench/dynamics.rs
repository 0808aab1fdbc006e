//! `evoloop bench dynamics`: the per-call cost of the rigid-body algorithms on a robot file, in
//! the JSON shape `scripts/pinocchio_bench.cpp` prints for Pinocchio, so the two can be timed in
//! interleaved rounds on the same machine (`scripts/pinocchio_bench.py`).

use crate::dynamics::Model;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use std::hint::black_box;
use std::time::Instant;

/// States cycled through (as on Pinocchio's side): enough to defeat a branch predictor that
/// learns one state, few enough to stay in L1.
pub const STATES: usize = 64;
/// Batches the calls are timed in (the median batch is reported).
const BATCHES: u64 = 10;

/// Nanoseconds per call of each algorithm.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PerCall {
    /// Inverse dynamics M qdd + V + G (Pinocchio's `rnea`; no friction).
    pub rnea: f64,
    /// M(q) by the composite rigid body algorithm (evoloop fills the whole matrix).
    pub crba: f64,
    /// Forward dynamics by Featherstone's articulated-body algorithm.
    pub aba: f64,
    /// Forward dynamics by RNEA + CRBA + Cholesky: the plant's route.
    pub forward_crba: f64,
}

/// What `evoloop bench dynamics` prints as JSON: per-call costs in the shape of
/// Pinocchio's `scripts/pinocchio_bench.cpp` output.
#[derive(Debug, Clone, Serialize)]
pub struct DynamicsBench {
    /// Which library was timed: always `"evoloop"` here (`"pinocchio"` on the C++ side).
    pub library: &'static str,
    /// The robot's name (`Model::name`).
    pub robot: String,
    /// Degrees of freedom of the robot (`Model::dof`).
    pub joints: usize,
    /// Calls asked for per algorithm, split into `BATCHES` timed batches.
    pub calls: u64,
    /// Median ns per call of each algorithm.
    pub ns_per_call: PerCall,
}

/// `STATES` random states (q, qd, qdd, tau) of an `n`-joint arm in [-1, 1], the same on every
/// call (seeded): what `bench dynamics` and `bench guard` time the algorithms on.
pub fn random_states(n: usize) -> Vec<[Vec<f64>; 4]> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut draw = || -> Vec<f64> { (0..n).map(|_| rng.gen_range(-1.0..=1.0)).collect() };
    (0..STATES)
        .map(|_| [draw(), draw(), draw(), draw()])
        .collect()
}

/// Time `calls` calls of each algorithm on `STATES` random states in [-1, 1] (friction dropped:
/// the rigid-body quantities Pinocchio computes), after a batch of warm-up calls each; ns per
/// call is the median over `BATCHES` batches.
pub fn measure(model: &Model, calls: u64) -> DynamicsBench {
    let mut model = model.clone();
    model.clear_friction();
    let n = model.dof();
    let states = random_states(n);
    let mut d = model.data();
    let mut out = vec![0.0; n];
    let m = &model;
    type Call<'a> = Box<dyn FnMut(&[Vec<f64>; 4], &mut crate::dynamics::Data, &mut [f64]) + 'a>;
    let mut algorithms: [Call; 4] = [
        Box::new(|[q, v, a, _], d, out| m.rnea(d, q, v, a, out)),
        Box::new(|[q, ..], d, out| out[0] = m.mass_matrix(d, q)[(0, 0)]),
        Box::new(|[q, v, _, tau], d, out| {
            m.forward_dynamics_aba(d, q, v, tau, out)
                .expect("random states of a loadable robot have M > 0")
        }),
        Box::new(|[q, v, _, tau], d, out| {
            m.forward_dynamics(d, q, v, tau, out)
                .expect("random states of a loadable robot have M > 0")
        }),
    ];
    // BATCHES rounds, each timing calls / BATCHES calls of every algorithm in turn; the median
    // batch is the figure, so a burst of noise on the shared machine spoils one batch of each
    // algorithm rather than one algorithm's whole figure.
    let per_batch = (calls / BATCHES).max(1);
    let mut ns = [[0.0; BATCHES as usize]; 4];
    for f in algorithms.iter_mut() {
        for k in 0..per_batch {
            f(&states[k as usize % STATES], &mut d, &mut out);
        }
    }
    for batch in 0..BATCHES as usize {
        for (f, ns) in algorithms.iter_mut().zip(ns.iter_mut()) {
            let t0 = Instant::now();
            for k in 0..per_batch {
                f(black_box(&states[k as usize % STATES]), &mut d, &mut out);
                black_box(&out);
            }
            ns[batch] = t0.elapsed().as_nanos() as f64 / per_batch as f64;
        }
    }
    let [rnea, crba, aba, forward_crba] = ns.map(|b| crate::stats::median(&b));
    DynamicsBench {
        library: "evoloop",
        robot: model.name.clone(),
        joints: n,
        calls,
        ns_per_call: PerCall {
            rnea,
            crba,
            aba,
            forward_crba,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_algorithm_is_timed_on_the_robot() {
        let model =
            crate::dynamics::load(&crate::node::launcher::shipped("config/robots/arm7.urdf"))
                .unwrap();
        let b = measure(&model, 1000);
        assert_eq!((b.joints, b.calls, b.library), (7, 1000, "evoloop"));
        let p = &b.ns_per_call;
        for (name, ns) in [
            ("rnea", p.rnea),
            ("crba", p.crba),
            ("aba", p.aba),
            ("forward_crba", p.forward_crba),
        ] {
            assert!(ns.is_finite() && ns > 0.0, "{name}: {ns}");
        }
    }
}
