//! A nominal model: the robot as its CAD model has it, wrong the way CAD models are.
//!
//! In simulation the robot's file is the truth. What a user has is a model of it whose masses,
//! centres of mass and inertias are off: parts are not where the drawing puts them, cables and
//! bolts are missing, densities are guessed. `CadError` is one body's error, as factors: the
//! mass times `mass`, each coordinate of the centre of mass (in the body's frame) times its
//! `com` factor, the inertia tensor about the centre of mass times `inertia`. A positive factor
//! keeps the tensor physical (positive definite, the triangle inequality), so every nominal
//! model is a valid robot. Friction, limits and kinematics are left as they are: the kinematics
//! of an arm is measured to fractions of a millimetre, its mass distribution is not.

use crate::model::Model;
use crate::spatial::Inertia;
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// One body's error, as factors on its mass, each centre-of-mass coordinate and its inertia
/// about the centre of mass.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CadError {
    /// Factor on the body's mass.
    pub mass: f64,
    /// Factors on the x, y and z of the centre of mass, in the body's frame.
    pub com: [f64; 3],
    /// Factor on the inertia tensor about the centre of mass.
    pub inertia: f64,
}

/// Each body's error drawn uniformly within 1 +- `spread` (0 <= spread < 1), from `seed`.
pub fn draw(bodies: usize, spread: f64, seed: u64) -> Vec<CadError> {
    assert!(
        (0.0..1.0).contains(&spread),
        "spread {spread} is not in [0, 1)"
    );
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut factor = || 1.0 + rng.gen_range(-spread..=spread);
    (0..bodies)
        .map(|_| CadError {
            mass: factor(),
            com: [factor(), factor(), factor()],
            inertia: factor(),
        })
        .collect()
}

/// `model` with each body's mass properties wrong by its `errors` entry.
pub fn perturbed(model: &Model, errors: &[CadError]) -> Model {
    assert_eq!(errors.len(), model.bodies.len(), "one CadError per body");
    let mut m = model.clone();
    for (b, e) in m.bodies.iter_mut().zip(errors) {
        let i = &b.inertia;
        let c = i.com();
        let com = glam::DVec3::new(c.x * e.com[0], c.y * e.com[1], c.z * e.com[2]);
        b.inertia = Inertia::from_com(i.m * e.mass, com, i.i_com() * e.inertia);
    }
    m.name = format!("{}_nominal", model.name);
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_stay_within_the_spread_and_one_seed_gives_one_error() {
        let e = draw(7, 0.2, 3);
        assert_eq!(e, draw(7, 0.2, 3));
        assert_ne!(e, draw(7, 0.2, 4));
        for x in &e {
            for f in [x.mass, x.inertia].iter().chain(&x.com) {
                assert!((0.8..=1.2).contains(f), "{f}");
            }
        }
        assert!(draw(3, 0.0, 1)
            .iter()
            .all(|x| x.mass == 1.0 && x.com == [1.0; 3]));
    }

    fn shipped(file: &str) -> Model {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/robots");
        crate::load(&dir.join(file)).unwrap()
    }

    /// max |a - b| over M(q), G(q) and V(q, qd) at a few states within the limits, relative to
    /// the largest entry of a's.
    fn dynamics_gap(a: &Model, b: &Model) -> f64 {
        let n = a.dof();
        let (mut da, mut db) = (a.data(), b.data());
        let (mut ta, mut tb) = (vec![0.0; n], vec![0.0; n]);
        let (mut gap, mut scale) = (0.0f64, 0.0f64);
        for k in 0..5 {
            let f = k as f64 / 4.0;
            let q: Vec<f64> = (a.bodies.iter())
                .map(|b| {
                    let (lo, hi) = b.limits.position_span();
                    lo + (0.1 + 0.8 * f) * (hi - lo)
                })
                .collect();
            let qd: Vec<f64> = (0..n).map(|j| 0.5 - 0.3 * j as f64 * f).collect();
            let ma = a.mass_matrix(&mut da, &q).clone();
            let mb = b.mass_matrix(&mut db, &q);
            gap = gap.max((&ma - mb).abs().max());
            scale = scale.max(ma.abs().max());
            a.rnea(&mut da, &q, &qd, &vec![0.0; n], &mut ta);
            b.rnea(&mut db, &q, &qd, &vec![0.0; n], &mut tb);
            for j in 0..n {
                gap = gap.max((ta[j] - tb[j]).abs());
                scale = scale.max(ta[j].abs());
            }
        }
        gap / scale
    }

    #[test]
    fn a_model_written_as_urdf_reads_back_with_the_same_dynamics() {
        let dir = std::env::temp_dir().join(format!("evoloop_nominal_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for file in ["arm3.toml", "arm7.urdf"] {
            let truth = shipped(file);
            let nominal = perturbed(&truth, &draw(truth.dof(), 0.2, 5));
            for m in [&truth, &nominal] {
                let path = dir.join(format!("{}.urdf", m.name));
                std::fs::write(&path, crate::urdf::to_urdf(m).unwrap()).unwrap();
                let back = crate::load(&path).unwrap();
                assert!(dynamics_gap(m, &back) < 1e-12, "{file}: {}", m.name);
            }
            // The nominal model is another arm: its dynamics differ by percents.
            let gap = dynamics_gap(&truth, &nominal);
            assert!((0.01..0.5).contains(&gap), "{file}: {gap}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
        // What URDF cannot carry is refused, not dropped.
        let e = crate::urdf::to_urdf(&shipped("industrial6.toml")).unwrap_err();
        assert!(matches!(e, crate::urdf::NotWritable::Joint(_)), "{e}");
        assert!(e.to_string().contains("armature"), "{e}");
    }
}
