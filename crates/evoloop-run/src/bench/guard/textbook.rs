//! The guard's references: the same arithmetic as a hot path, written the plain way and sharing
//! none of its code, so a change that slows the hot path cannot slow its reference too.
//!
//! - `Rnea`: recursive Newton-Euler as a textbook states it (Craig's outward and inward
//!   recursions on 3-vectors, a body's frame at its joint), on `[f64; 3]` arrays: no spatial
//!   algebra, no glam, none of `evoloop_dynamics`' passes. It reads only the robot's numbers.
//!   Its torques and its mass matrix (one inverse dynamics per column) are checked against
//!   evoloop's, so the two time the same work.
//! - `BareSwarm`: a particle swarm's flight written as one scalar loop with its own xorshift
//!   generator, on the guard's trivial objective: the arithmetic an evaluation of the optimisers
//!   costs without their bookkeeping.

use crate::dynamics::{JointKind, Model};

type V3 = [f64; 3];
/// Row-major 3x3.
type M3 = [[f64; 3]; 3];

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn mul(m: &M3, v: V3) -> V3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}
/// mᵀ v.
fn mul_t(m: &M3, v: V3) -> V3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}
fn mat_mul(a: &M3, b: &M3) -> M3 {
    let mut c = [[0.0; 3]; 3];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

/// One body as the textbook needs it: where its joint sits on the parent, the joint's axis, and
/// the body's mass, centre of mass and inertia about it, all in the body's own frame.
struct Link {
    parent: Option<usize>,
    revolute: bool,
    /// Parent coordinates -> joint coordinates before the joint moves.
    placement: M3,
    /// The joint's origin in parent coordinates.
    origin: V3,
    axis: V3,
    mass: f64,
    com: V3,
    inertia: M3,
    armature: f64,
}

/// Recursive Newton-Euler on plain arrays, with its buffers (allocated once).
pub struct Rnea {
    links: Vec<Link>,
    /// Gravity as the base's upward acceleration.
    base: V3,
    /// Per body at the last call: parent -> body rotation, the body's origin in parent
    /// coordinates, angular velocity and acceleration, the origin's linear acceleration, and
    /// the force and moment the parent exerts on the body.
    rot: Vec<M3>,
    pos: Vec<V3>,
    w: Vec<V3>,
    dw: Vec<V3>,
    dv: Vec<V3>,
    f: Vec<V3>,
    n: Vec<V3>,
    /// Zero velocities and one unit acceleration: `mass_matrix`'s columns.
    zero: Vec<f64>,
    unit: Vec<f64>,
    column: Vec<f64>,
}

impl Rnea {
    /// The robot's numbers, read once.
    pub fn new(model: &Model) -> Rnea {
        let links: Vec<Link> = model
            .bodies
            .iter()
            .map(|b| Link {
                parent: b.parent,
                revolute: match b.kind {
                    JointKind::Revolute => true,
                    JointKind::Prismatic => false,
                },
                // The columns of eᵀ are the rows of e.
                placement: b.placement.e.transpose().to_cols_array_2d(),
                origin: b.placement.r.to_array(),
                axis: b.axis.to_array(),
                mass: b.inertia.m,
                com: b.inertia.com().to_array(),
                inertia: b.inertia.i_com().transpose().to_cols_array_2d(),
                armature: b.armature,
            })
            .collect();
        let n = links.len();
        Rnea {
            links,
            base: (-model.gravity).to_array(),
            rot: vec![[[0.0; 3]; 3]; n],
            pos: vec![[0.0; 3]; n],
            w: vec![[0.0; 3]; n],
            dw: vec![[0.0; 3]; n],
            dv: vec![[0.0; 3]; n],
            f: vec![[0.0; 3]; n],
            n: vec![[0.0; 3]; n],
            zero: vec![0.0; n],
            unit: vec![0.0; n],
            column: vec![0.0; n],
        }
    }

    /// tau = M(q) qdd + V(q, qd) + G(q) (no friction), gravity dropped when `gravity` is false.
    pub fn torques(&mut self, q: &[f64], qd: &[f64], qdd: &[f64], gravity: bool, tau: &mut [f64]) {
        let base = if gravity { self.base } else { [0.0; 3] };
        // Outward: each body's rotation, velocities and accelerations from its parent's.
        for i in 0..self.links.len() {
            let l = &self.links[i];
            let (c, s) = (q[i].cos(), q[i].sin());
            let a = l.axis;
            let (rot, pos) = if l.revolute {
                // Parent -> body: the joint's rotation by -q about its axis after the placement
                // (Rodrigues, transposed).
                let k = 1.0 - c;
                let joint = [
                    [
                        c + k * a[0] * a[0],
                        k * a[0] * a[1] + s * a[2],
                        k * a[0] * a[2] - s * a[1],
                    ],
                    [
                        k * a[1] * a[0] - s * a[2],
                        c + k * a[1] * a[1],
                        k * a[1] * a[2] + s * a[0],
                    ],
                    [
                        k * a[2] * a[0] + s * a[1],
                        k * a[2] * a[1] - s * a[0],
                        c + k * a[2] * a[2],
                    ],
                ];
                (mat_mul(&joint, &l.placement), l.origin)
            } else {
                (
                    l.placement,
                    add(l.origin, mul_t(&l.placement, scale(a, q[i]))),
                )
            };
            let (w_p, dw_p, dv_p) = match l.parent {
                Some(p) => (self.w[p], self.dw[p], self.dv[p]),
                None => ([0.0; 3], [0.0; 3], base),
            };
            let carried = add(dv_p, add(cross(dw_p, pos), cross(w_p, cross(w_p, pos))));
            let (w, dw, dv) = if l.revolute {
                let w_in = mul(&rot, w_p);
                let w = add(w_in, scale(a, qd[i]));
                let dw = add(
                    add(mul(&rot, dw_p), scale(a, qdd[i])),
                    cross(w_in, scale(a, qd[i])),
                );
                (w, dw, mul(&rot, carried))
            } else {
                let w = mul(&rot, w_p);
                let slide = add(scale(cross(w, scale(a, qd[i])), 2.0), scale(a, qdd[i]));
                (w, mul(&rot, dw_p), add(mul(&rot, carried), slide))
            };
            let dv_com = add(dv, add(cross(dw, l.com), cross(w, cross(w, l.com))));
            let force = scale(dv_com, l.mass);
            let moment = add(mul(&l.inertia, dw), cross(w, mul(&l.inertia, w)));
            (self.rot[i], self.pos[i]) = (rot, pos);
            (self.w[i], self.dw[i], self.dv[i]) = (w, dw, dv);
            self.f[i] = force;
            self.n[i] = add(moment, cross(l.com, force));
        }
        // Inward: each body's joint takes the axis' part of what holds it and passes it on.
        for i in (0..self.links.len()).rev() {
            let l = &self.links[i];
            let along = if l.revolute { self.n[i] } else { self.f[i] };
            tau[i] = dot(l.axis, along) + l.armature * qdd[i];
            if let Some(p) = l.parent {
                let f_p = mul_t(&self.rot[i], self.f[i]);
                let n_p = add(mul_t(&self.rot[i], self.n[i]), cross(self.pos[i], f_p));
                self.f[p] = add(self.f[p], f_p);
                self.n[p] = add(self.n[p], n_p);
            }
        }
    }

    /// M(q) column by column: the torques of a unit acceleration at rest without gravity.
    /// `m` is n x n, row-major.
    pub fn mass_matrix(&mut self, q: &[f64], m: &mut [f64]) {
        let n = self.links.len();
        let (zero, mut unit, mut column) = (
            std::mem::take(&mut self.zero),
            std::mem::take(&mut self.unit),
            std::mem::take(&mut self.column),
        );
        for j in 0..n {
            unit[j] = 1.0;
            self.torques(q, &zero, &unit, false, &mut column);
            unit[j] = 0.0;
            for i in 0..n {
                m[i * n + j] = column[i];
            }
        }
        (self.zero, self.unit, self.column) = (zero, unit, column);
    }
}

impl Rnea {
    /// Where this recursion and evoloop's `model` (friction cleared) differ at a state, beyond
    /// round-off (torques to 1e-9 relative, M(q) to 1e-9): None where they agree.
    pub fn disagreement(
        &mut self,
        model: &Model,
        data: &mut crate::dynamics::Data,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
    ) -> Option<String> {
        let n = model.dof();
        let (mut ours, mut theirs, mut m) = (vec![0.0; n], vec![0.0; n], vec![0.0; n * n]);
        model.rnea(data, q, qd, qdd, &mut ours);
        self.torques(q, qd, qdd, true, &mut theirs);
        if let Some(i) =
            (0..n).find(|&i| (ours[i] - theirs[i]).abs() > 1e-9 * ours[i].abs().max(1.0))
        {
            return Some(format!(
                "{}: joint {i}'s torque {} against {} at q = {q:?}",
                model.name, ours[i], theirs[i]
            ));
        }
        let mass = model.mass_matrix(data, q);
        self.mass_matrix(q, &mut m);
        (0..n * n)
            .find(|&k| (mass[(k / n, k % n)] - m[k]).abs() > 1e-9)
            .map(|k| {
                format!(
                    "{}: M[{},{}] {} against {} at q = {q:?}",
                    model.name,
                    k / n,
                    k % n,
                    mass[(k / n, k % n)],
                    m[k]
                )
            })
    }
}

/// A particle swarm's flight on the trivial objective f(x) = x_0: a particle's random numbers
/// drawn into a buffer, then its update in one loop over the coordinates, compiled four lanes
/// wide where the CPU has AVX2, as the optimisers' flights are (so the ratio holds on a host
/// without it too).
pub struct BareSwarm {
    dim: usize,
    x: Vec<f64>,
    v: Vec<f64>,
    best_x: Vec<f64>,
    best_f: Vec<f64>,
    swarm_x: Vec<f64>,
    swarm_f: f64,
    draws: Vec<f64>,
    state: u64,
}

impl BareSwarm {
    /// A swarm of `population` particles in `dim` dimensions, placed at fixed pseudo-random
    /// points in [-1, 1) (the same every time), at rest and with no best yet.
    pub fn new(population: usize, dim: usize) -> BareSwarm {
        let mut s = BareSwarm {
            dim,
            x: vec![0.0; population * dim],
            v: vec![0.0; population * dim],
            best_x: vec![0.0; population * dim],
            best_f: vec![f64::INFINITY; population],
            swarm_x: vec![0.0; dim],
            swarm_f: f64::INFINITY,
            draws: vec![0.0; 2 * dim],
            state: 0x9E37_79B9_7F4A_7C15,
        };
        for k in 0..s.x.len() {
            s.x[k] = 2.0 * s.uniform() - 1.0;
        }
        s
    }

    /// xorshift64*, in [0, 1).
    fn uniform(&mut self) -> f64 {
        self.state ^= self.state >> 12;
        self.state ^= self.state << 25;
        self.state ^= self.state >> 27;
        (self.state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// One generation: every particle flies, is evaluated and updates the bests. Returns the
    /// evaluations made (the population).
    pub fn generation(&mut self) -> usize {
        let (d, population) = (self.dim, self.best_f.len());
        for i in 0..population {
            for k in 0..2 * d {
                self.draws[k] = self.uniform();
            }
            let row = i * d..(i + 1) * d;
            fly(
                &mut self.x[row.clone()],
                &mut self.v[row.clone()],
                &self.best_x[row.clone()],
                &self.swarm_x,
                &self.draws,
            );
            let f = self.x[i * d];
            if f < self.best_f[i] {
                self.best_f[i] = f;
                self.best_x[row.clone()].copy_from_slice(&self.x[row.clone()]);
            }
            if f < self.swarm_f {
                self.swarm_f = f;
                self.swarm_x.copy_from_slice(&self.x[row]);
            }
        }
        population
    }

    /// The best value found (kept so the work is not optimised away).
    pub fn best(&self) -> f64 {
        self.swarm_f
    }
}

/// One particle's update, four lanes wide where the CPU has AVX2.
fn fly(x: &mut [f64], v: &mut [f64], p: &[f64], g: &[f64], draws: &[f64]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has just been checked for AVX2.
        return unsafe { fly_avx2(x, v, p, g, draws) };
    }
    fly_body(x, v, p, g, draws)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fly_avx2(x: &mut [f64], v: &mut [f64], p: &[f64], g: &[f64], draws: &[f64]) {
    fly_body(x, v, p, g, draws)
}

#[inline(always)]
fn fly_body(x: &mut [f64], v: &mut [f64], p: &[f64], g: &[f64], draws: &[f64]) {
    let d = x.len();
    let (v, p, g, r1, r2) = (&mut v[..d], &p[..d], &g[..d], &draws[..d], &draws[d..2 * d]);
    for j in 0..d {
        let nv = (0.7 * v[j] + 2.0 * r1[j] * (p[j] - x[j]) + 2.0 * r2[j] * (g[j] - x[j]))
            .clamp(-0.4, 0.4);
        let nx = x[j] + nv;
        let cx = nx.clamp(-1.0, 1.0);
        v[j] = if cx == nx { nv } else { 0.0 };
        x[j] = cx;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn robots() -> Vec<Model> {
        // The shipped arms (the D-H one with its drives' armature), and a branched tree with a
        // prismatic joint and tilted axes: the joints the arms do not have.
        [
            "config/robots/arm7.urdf",
            "config/robots/arm3.urdf",
            "config/robots/industrial6.toml",
            "tests/robots/branched.urdf",
        ]
        .iter()
        .map(|p| crate::dynamics::load(&crate::node::launcher::shipped(p)).unwrap())
        .collect()
    }

    /// The textbook's torques and mass matrix are evoloop's (so the guard times the same work),
    /// on random states of the shipped arms.
    #[test]
    fn the_textbook_recursion_gives_evoloops_torques_and_mass_matrix() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for mut model in robots() {
            model.clear_friction();
            let n = model.dof();
            let mut textbook = Rnea::new(&model);
            let mut d = model.data();
            for _ in 0..20 {
                let mut draw =
                    || -> Vec<f64> { (0..n).map(|_| rng.gen_range(-2.0..2.0)).collect() };
                let (q, qd, qdd) = (draw(), draw(), draw());
                // Torques to 1e-9 relative and M(q) to 1e-9, joint by joint.
                assert_eq!(textbook.disagreement(&model, &mut d, &q, &qd, &qdd), None);
            }
        }
    }

    #[test]
    fn the_bare_swarm_descends_on_its_objective() {
        let mut s = BareSwarm::new(30, 30);
        assert_eq!(s.generation(), 30);
        let first = s.best();
        for _ in 0..200 {
            s.generation();
        }
        assert!(
            s.best() < first && s.best() >= -1.0,
            "{first} -> {}",
            s.best()
        );
    }
}
