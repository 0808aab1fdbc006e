//! How far a model is from the arm along a path: whether a model that tracks well is right or
//! only stiff. An inflated M-hat acts as a higher feedback gain under computed torque (the law's
//! M-hat (qdd_d + K_v e_dot + K_p e) multiplies the feedback too), which tracking rewards; the
//! tracking error alone cannot tell the two apart.

use crate::dynamics::Model;
use nalgebra::DMatrix;
use serde::Serialize;

/// A model against the arm at the states of a path (the simulator's truth judges the model here,
/// after the fact; nothing of it reaches a controller).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ModelError {
    /// Mean over the path of |M-hat - M|_F / |M|_F.
    pub m_rel: f64,
    /// Mean over the path of tr(M-hat) / tr(M): above 1, an inflated model (a stiffer loop).
    pub m_scale: f64,
    /// |V-hat - V|_2 / |V|_2 over the whole path, V the arm's velocity-dependent torque
    /// (Coriolis, centrifugal and friction: V-hat has to explain all of it).
    pub v_rel: f64,
    /// |G-hat - G|_2 / |G|_2 over the whole path.
    pub g_rel: f64,
    /// M-hat's smallest eigenvalue on the path, and M's (the scale it is judged against).
    pub min_eig: f64,
    /// M's smallest eigenvalue on the path (the arm's own).
    pub min_eig_arm: f64,
}

/// A model's terms at (q, qd): M into the matrix, V and G into the slices.
pub trait ArmTerms {
    /// Write M(q) into `m` (n x n), the velocity-dependent torque V(q, qd) into `v` and the
    /// gravity torque G(q) into `g`.
    fn terms(&mut self, q: &[f64], qd: &[f64], m: &mut DMatrix<f64>, v: &mut [f64], g: &mut [f64]);
}

/// A rigid-body model's terms: M(q), V(q, qd) + friction(qd), G(q) (the arm's own, or the
/// nominal model's).
pub struct RigidBody<'a> {
    model: &'a Model,
    data: crate::dynamics::Data,
    friction: Vec<f64>,
}

impl<'a> RigidBody<'a> {
    /// The terms of `model` (its friction counted in V).
    pub fn new(model: &'a Model) -> Self {
        RigidBody {
            data: model.data(),
            friction: vec![0.0; model.dof()],
            model,
        }
    }
}

impl ArmTerms for RigidBody<'_> {
    fn terms(&mut self, q: &[f64], qd: &[f64], m: &mut DMatrix<f64>, v: &mut [f64], g: &mut [f64]) {
        let (a, d) = (self.model, &mut self.data);
        m.copy_from(a.mass_matrix(d, q));
        a.coriolis(d, q, qd, v);
        a.friction(qd, &mut self.friction);
        v.iter_mut().zip(&self.friction).for_each(|(v, f)| *v += f);
        a.gravity_torque(d, q, g);
    }
}

/// An identified model's terms: its network's M-hat, V-hat, G-hat.
impl ArmTerms for &evoloop_rkgnn::network::Network {
    fn terms(&mut self, q: &[f64], qd: &[f64], m: &mut DMatrix<f64>, v: &mut [f64], g: &mut [f64]) {
        let n = self.dof();
        let mut buf = [0.0; crate::msg::MAX_JOINTS * crate::msg::MAX_JOINTS];
        self.inertia_and_velocity(q, qd, &mut buf, v);
        // Row-major into column-major: the same numbers, M-hat being symmetric by construction.
        m.copy_from_slice(&buf[..n * n]);
        self.gravity(q, g);
    }
}

/// `model` against `arm` at the states `path` ((q, qd) pairs).
pub fn model_error(
    arm: &Model,
    path: &[(Vec<f64>, Vec<f64>)],
    model: &mut dyn ArmTerms,
) -> ModelError {
    let n = arm.dof();
    let mut truth = RigidBody::new(arm);
    let (mut m, mut mh) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
    let (mut v, mut vh, mut g, mut gh) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut m_rel, mut m_scale) = (0.0, 0.0);
    let [mut dv, mut nv, mut dg, mut ng] = [0.0; 4];
    let (mut min_eig, mut min_eig_arm) = (f64::INFINITY, f64::INFINITY);
    let lowest = |a: &DMatrix<f64>| a.clone().symmetric_eigenvalues().min();
    for (q, qd) in path {
        truth.terms(q, qd, &mut m, &mut v, &mut g);
        model.terms(q, qd, &mut mh, &mut vh, &mut gh);
        m_rel += (&mh - &m).norm() / m.norm();
        m_scale += mh.trace() / m.trace();
        for j in 0..n {
            dv += (vh[j] - v[j]).powi(2);
            nv += v[j] * v[j];
            dg += (gh[j] - g[j]).powi(2);
            ng += g[j] * g[j];
        }
        min_eig = min_eig.min(lowest(&mh));
        min_eig_arm = min_eig_arm.min(lowest(&m));
    }
    let k = path.len().max(1) as f64;
    ModelError {
        m_rel: m_rel / k,
        m_scale: m_scale / k,
        v_rel: (dv / nv).sqrt(),
        g_rel: (dg / ng).sqrt(),
        min_eig,
        min_eig_arm,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arm3() -> Model {
        let f =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/robots/arm3.toml");
        crate::dynamics::load(&f).unwrap()
    }

    fn path(arm: &Model) -> Vec<(Vec<f64>, Vec<f64>)> {
        (0..20)
            .map(|k| {
                let s = k as f64 / 19.0;
                let q = (arm.bodies.iter())
                    .map(|b| {
                        let (lo, hi) = b.limits.position_span();
                        lo + (0.2 + 0.6 * s) * (hi - lo)
                    })
                    .collect();
                (q, vec![1.0 - s, 0.5, -0.3 * s])
            })
            .collect()
    }

    #[test]
    fn the_arm_has_no_error_and_a_model_twice_as_heavy_shows_as_inflated() {
        let arm = arm3();
        let p = path(&arm);
        let e = model_error(&arm, &p, &mut RigidBody::new(&arm));
        assert!(
            e.m_rel < 1e-12 && e.v_rel < 1e-12 && e.g_rel < 1e-12,
            "{e:?}"
        );
        assert!(
            (e.m_scale - 1.0).abs() < 1e-12 && e.min_eig == e.min_eig_arm,
            "{e:?}"
        );
        // Twice the masses and inertias: M, V (bar friction) and G all double.
        let errors = vec![
            crate::dynamics::nominal::CadError {
                mass: 2.0,
                com: [1.0; 3],
                inertia: 2.0
            };
            3
        ];
        let heavy = crate::dynamics::nominal::perturbed(&arm, &errors);
        let e = model_error(&arm, &p, &mut RigidBody::new(&heavy));
        assert!(
            (e.m_rel - 1.0).abs() < 1e-9 && (e.m_scale - 2.0).abs() < 1e-9,
            "{e:?}"
        );
        assert!((e.g_rel - 1.0).abs() < 1e-9 && (e.min_eig / e.min_eig_arm - 2.0).abs() < 1e-9);
    }
}
