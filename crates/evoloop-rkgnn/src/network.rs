//! The function network N_f of the RKGNN paper (Section 3, eqs. 5-10, Figs. 2-5): shape-adaptive
//! Gaussian RBF sub-networks, one per component of the arm's dynamics and of its unknown servo,
//! so that
//!   x' = N_f(x; r) = [theta'; M^-1(theta) (tau(r - x) - V(theta, theta') - G(theta))],
//! x = [theta; theta'], r = [theta_d; theta_d'] the servo's reference.
//!
//! Every sub-network is eq. 7, sum_l W_kl phi_l(y) with phi_l = exp(-|y - c_l|^2 / s_l^2)
//! (eq. 6); the parameters of one RBF sit together as [centre (inputs), width s, weights
//! (outputs)]. The sub-networks, for n joints:
//! - Torque network (Fig. 3): per joint j a proportional sub-network on theta_d,j - theta_j and a
//!   derivative one on theta_d,j' - theta_j', 3 RBFs each, one output; tau_j is their sum less
//!   its value at zero error. We read Fig. 3's "proportional and derivative networks" per joint,
//!   as a decentralised P-D servo (one axis amplifier per joint, as industrial arms have); a
//!   coupled servo would take the whole error vector. The zero-error offset is removed because a
//!   P-D servo gives no torque at zero error (the paper: "if detailed information of the
//!   controller is known, the structure of the network can be altered accordingly"). It removes
//!   one ambiguity, a constant torque the data cannot tell from gravity, not all: along one
//!   trajectory the error and the joint positions move together, so a servo characteristic and
//!   a gravity network can still trade torque (see the issue notes on the identified G-hat).
//! - Inertia network (Fig. 4): one sub-network on theta per entry of the diagonal and upper
//!   triangle (n(n+1)/2 of them), 10 RBFs each; M-hat is filled symmetrically from them, so it is
//!   symmetric by construction. Positive definiteness is not built in: the identification's
//!   constraints (eqs. 14-16) enforce it and a model is checked before use.
//! - Velocity network (Fig. 5, eqs. 8-10): per joint i a sub-network on theta, 3 RBFs, with the
//!   n(n-1)/2 + n outputs B_i(theta) and C_i(theta), V_i = B_i [theta' theta'] + C_i [theta'^2].
//!   With `RbfCounts::velocity` = 0 there is no velocity network: V-hat comes from M-hat's
//!   Christoffel symbols (`christoffel`), so that eq. 3 holds by construction.
//! - Gravity network: one sub-network on theta with n RBFs and n outputs.
//!
//! `Network` evaluates N_f and the model parts without allocating (stack arrays of
//! `MAX_JOINTS`); the parameters are one flat vector, the EA's object variables.

use evoloop_linalg::{solve, sym_eig_range, Mat};
use evoloop_msg::MAX_JOINTS;
use serde::{Deserialize, Serialize};

/// RBF counts per sub-network (the paper's: 3, 10, 3 and n).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RbfCounts {
    /// RBFs per servo sub-network; 0 = a linear servo, tau_j = k_p,j e_j + k_d,j e_j' (see
    /// `Layout::gains`).
    pub torque: usize,
    /// RBFs per inertia sub-network (one sub-network per entry of M-hat's upper triangle).
    pub inertia: usize,
    /// RBFs per velocity sub-network; 0 = no velocity network, V-hat from M-hat's Christoffel
    /// symbols (eq. 3 by construction).
    pub velocity: usize,
    /// RBFs of the gravity network (the paper: n).
    pub gravity: usize,
}

impl RbfCounts {
    /// Section 5.1: 3 per torque sub-network, 10 per inertia sub-network, 3 per velocity
    /// sub-network, and n for the gravity network.
    pub fn paper(n: usize) -> Self {
        Self {
            torque: 3,
            inertia: 10,
            velocity: 3,
            gravity: n,
        }
    }

    /// The paper's counts with a linear servo (torque = 0): the P-D servo of the paper's
    /// premise with its two gains per joint as the only servo parameters. The paper allows it
    /// ("if detailed information of the controller is known, the structure of the network can
    /// be altered accordingly"), and it is what makes gravity identifiable: under a P-D servo
    /// the error sits near e = G / k_p, and an RBF characteristic can take any value there, so
    /// that value and a constant part of G-hat trade one for the other with identical motion.
    /// A line through zero ties the servo's torque at the operating error to its slope, which
    /// the motion around it does determine.
    pub fn linear_servo(n: usize) -> Self {
        Self {
            torque: 0,
            ..Self::paper(n)
        }
    }

    /// Whether the servo is linear (`torque` = 0): gains k_p, k_d per joint instead of RBF
    /// sub-networks.
    pub fn is_linear_servo(&self) -> bool {
        self.torque == 0
    }
}

/// Shape of one sub-network: inputs, outputs, RBFs; its parameters start at `offset`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SubNet {
    /// Number of inputs y: the length of each RBF's centre.
    pub inputs: usize,
    /// Number of outputs: the output weights per RBF.
    pub outputs: usize,
    /// Number of RBFs.
    pub rbfs: usize,
    /// Index of the sub-network's first parameter in the flat parameter vector.
    pub offset: usize,
}

impl SubNet {
    /// Parameters of one RBF: centre, width, output weights.
    pub fn per_rbf(&self) -> usize {
        self.inputs + 1 + self.outputs
    }

    /// Number of parameters the sub-network holds: `rbfs` times `per_rbf()`.
    pub fn len(&self) -> usize {
        self.rbfs * self.per_rbf()
    }

    /// Whether it has no RBFs, hence no parameters and an output of 0.
    pub fn is_empty(&self) -> bool {
        self.rbfs == 0
    }

    /// Where RBF l's output weights sit in the flat parameter vector.
    pub fn weights(&self, l: usize) -> std::ops::Range<usize> {
        let b = self.offset + l * self.per_rbf() + self.inputs + 1;
        b..b + self.outputs
    }

    /// Every output weight of the sub-network, RBF by RBF.
    pub fn all_weights(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.rbfs).flat_map(|l| self.weights(l))
    }

    /// RBF l's centre, width s and output weights.
    #[inline]
    fn rbf<'p>(&self, p: &'p [f64], l: usize) -> (&'p [f64], f64, &'p [f64]) {
        let block = self.per_rbf();
        let b = &p[self.offset + l * block..self.offset + (l + 1) * block];
        let (centre, rest) = b.split_at(self.inputs);
        (centre, rest[0], &rest[1..])
    }

    /// Eq. 7: out_k = sum_l W_kl exp(-|y - c_l|^2 / s_l^2), out overwritten.
    ///
    /// An RBF whose output weights are all zero is skipped: for finite inputs and parameters of
    /// ordinary magnitude phi is finite and not negative, so a zero weight's terms are +-0, and
    /// adding +-0 to a sum that starts at +0 leaves it bit for bit as it was (a sum of nonzero
    /// terms is never -0). In the control cycle it costs one comparison per RBF. Identification's
    /// least squares build each weight's column from a model whose other weights are all zero
    /// (`evoloop_identify`'s `design`): arm7's columns cost one exp per sample, not one per RBF
    /// of the whole model (a 14 s identify-mode run of arm7: 41 s -> 31 s, 2026-12-06). A NaN
    /// input gives 0, not NaN, from a sub-network whose weights are all zero: the cycle refuses
    /// non-finite states before a model sees them.
    #[inline]
    pub fn eval(&self, p: &[f64], y: &[f64], out: &mut [f64]) {
        out[..self.outputs].fill(0.0);
        for l in 0..self.rbfs {
            let (centre, s, w) = self.rbf(p, l);
            if w.iter().all(|&w| w == 0.0) {
                continue; // adds nothing (see above)
            }
            let (phi, _) = phi(centre, s, &y[..self.inputs]);
            for (o, w) in out[..self.outputs].iter_mut().zip(w) {
                *o += w * phi;
            }
        }
    }

    /// A one-output sub-network's value (eq. 7) and its gradient in the inputs into `grad`,
    /// in one pass: d out / d y = sum_l W_l phi_l(y) (-2 (y - c_l) / s_l^2).
    #[inline]
    pub fn value_and_gradient(&self, p: &[f64], y: &[f64], grad: &mut [f64]) -> f64 {
        let y = &y[..self.inputs];
        grad[..self.inputs].fill(0.0);
        let mut value = 0.0;
        for l in 0..self.rbfs {
            let (centre, s, w) = self.rbf(p, l);
            if w[0] == 0.0 {
                continue; // adds nothing (as in `eval`)
            }
            let (phi, s2) = phi(centre, s, y);
            let wphi = w[0] * phi;
            value += wphi;
            let f = -2.0 * wphi / s2;
            for (g, (yi, ci)) in grad.iter_mut().zip(y.iter().zip(centre)) {
                *g += f * (yi - ci);
            }
        }
        value
    }
}

/// Eq. 6 for one RBF: phi = exp(-|y - c|^2 / s^2), and the s^2 it divided by.
#[inline]
fn phi(centre: &[f64], s: f64, y: &[f64]) -> (f64, f64) {
    let mut d2 = 0.0;
    for (yi, ci) in y.iter().zip(centre) {
        let d = yi - ci;
        d2 += d * d;
    }
    let s2 = s * s + WIDTH_FLOOR;
    ((-d2 / s2).exp(), s2)
}

/// Added to s^2 so that a width the search drives to zero gives a narrow bump, never 0/0.
const WIDTH_FLOOR: f64 = 1e-12;

/// Where each sub-network's parameters sit in the flat vector.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Layout {
    /// Joint count n.
    pub n: usize,
    /// The RBF counts the layout was built from.
    pub counts: RbfCounts,
    /// Per joint: proportional, then derivative sub-network (inputs 1, output 1).
    pub torque: Vec<[SubNet; 2]>,
    /// Upper-triangle entries (a, b), a <= b, row by row, and their sub-networks (inputs n).
    pub inertia: Vec<((usize, usize), SubNet)>,
    /// Per joint i: outputs [B_i (pairs a < b); C_i (n)].
    pub velocity: Vec<SubNet>,
    /// The gravity network: inputs theta (n), outputs G-hat (n).
    pub gravity: SubNet,
    /// With a linear servo: where its gains sit, [k_p,j, k_d,j] per joint (2n parameters at
    /// the end); None with RBF servo sub-networks.
    pub gains: Option<usize>,
    /// Total parameter count: the length of the flat parameter vector.
    pub len: usize,
}

impl Layout {
    /// The layout of N_f for `n` joints with `counts`: the sub-networks one after the other
    /// (torque, inertia, velocity, gravity), then a linear servo's gains. Panics unless
    /// 1 <= n <= `MAX_JOINTS`.
    pub fn new(n: usize, counts: RbfCounts) -> Self {
        assert!(
            (1..=MAX_JOINTS).contains(&n),
            "1..={MAX_JOINTS} joints, got {n}"
        );
        let mut offset = 0;
        let mut net = |inputs, outputs, rbfs| {
            let s = SubNet {
                inputs,
                outputs,
                rbfs,
                offset,
            };
            offset += s.len();
            s
        };
        let torque = (0..n)
            .map(|_| [net(1, 1, counts.torque), net(1, 1, counts.torque)])
            .collect();
        let mut inertia = Vec::new();
        for a in 0..n {
            for b in a..n {
                inertia.push(((a, b), net(n, 1, counts.inertia)));
            }
        }
        let pairs = n * (n - 1) / 2;
        let velocity = (0..n).map(|_| net(n, pairs + n, counts.velocity)).collect();
        let gravity = net(n, n, counts.gravity);
        let gains = counts.is_linear_servo().then_some(offset);
        if gains.is_some() {
            offset += 2 * n;
        }
        Self {
            n,
            counts,
            torque,
            inertia,
            velocity,
            gravity,
            gains,
            len: offset,
        }
    }

    /// Every sub-network with its role, for initialisation and bounds.
    pub fn subnets(&self) -> impl Iterator<Item = (Part, &SubNet)> {
        let torque = self.torque.iter().enumerate().flat_map(|(j, pd)| {
            [
                (Part::Proportional(j), &pd[0]),
                (Part::Derivative(j), &pd[1]),
            ]
        });
        let inertia = self
            .inertia
            .iter()
            .map(|((a, b), s)| (Part::Inertia(*a, *b), s));
        let velocity = self
            .velocity
            .iter()
            .enumerate()
            .map(|(i, s)| (Part::Velocity(i), s));
        torque
            .chain(inertia)
            .chain(velocity)
            .chain(std::iter::once((Part::Gravity, &self.gravity)))
    }
}

/// What a sub-network stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// Joint j's proportional servo sub-network (input theta_d,j - theta_j).
    Proportional(usize),
    /// Joint j's derivative servo sub-network (input theta_d,j' - theta_j').
    Derivative(usize),
    /// The inertia sub-network of M-hat's entry (a, b), a <= b.
    Inertia(usize, usize),
    /// Joint i's velocity sub-network (outputs B_i and C_i).
    Velocity(usize),
    /// The gravity network (G-hat).
    Gravity,
}

/// N_f with its parameters: the identified model.
#[derive(Debug, Clone)]
pub struct Network {
    /// Where each sub-network's parameters sit in the parameter vector.
    pub layout: Layout,
    params: Vec<f64>,
    /// The servo sub-networks' values at zero error, fixed by the parameters.
    zero: ServoZero,
}

/// Per joint, the proportional and derivative sub-networks' values at zero error (P_j(0) at
/// 2j, D_j(0) at 2j + 1): the offsets the torque network subtracts. They depend on the
/// parameters only, so they are computed once per parameter set, not per evaluation.
pub type ServoZero = [f64; 2 * MAX_JOINTS];

/// `ServoZero` for parameters `p`.
pub fn servo_zero(layout: &Layout, p: &[f64]) -> ServoZero {
    let mut z = [0.0; 2 * MAX_JOINTS];
    let mut out = [0.0; 1];
    for (j, nets) in layout.torque.iter().enumerate() {
        for (k, net) in nets.iter().enumerate() {
            net.eval(p, &[0.0], &mut out);
            z[2 * j + k] = out[0];
        }
    }
    z
}

impl Network {
    /// The network of `layout` with parameters `params` in `Layout` order. Panics if
    /// `params.len()` is not `layout.len`.
    pub fn new(layout: Layout, params: Vec<f64>) -> Self {
        assert_eq!(params.len(), layout.len, "parameter count");
        let zero = servo_zero(&layout, &params);
        Self {
            layout,
            params,
            zero,
        }
    }

    /// The parameters in `Layout` order.
    pub fn params(&self) -> &[f64] {
        &self.params
    }

    /// Replace the parameters (same layout, `p.len() == layout.len`) without allocating.
    pub fn set_params(&mut self, p: &[f64]) {
        self.params.copy_from_slice(p);
        self.zero = servo_zero(&self.layout, &self.params);
    }

    /// Joint count n.
    pub fn dof(&self) -> usize {
        self.layout.n
    }

    /// M-hat(theta) into `m` (row-major, stride n), symmetric by construction.
    pub fn inertia(&self, theta: &[f64], m: &mut Mat) {
        inertia(&self.layout, &self.params, theta, m)
    }

    /// V-hat(theta, theta') (eqs. 8-10, or M-hat's Christoffel symbols).
    pub fn velocity(&self, theta: &[f64], theta_d: &[f64], v: &mut [f64]) {
        velocity(&self.layout, &self.params, theta, theta_d, v)
    }

    /// M-hat(theta) and V-hat(theta, theta') together: one pass over the inertia network when
    /// V-hat comes from M-hat (`inertia` then `velocity` would evaluate its RBFs twice).
    pub fn inertia_and_velocity(&self, theta: &[f64], theta_d: &[f64], m: &mut Mat, v: &mut [f64]) {
        inertia_and_velocity(&self.layout, &self.params, theta, theta_d, m, v)
    }

    /// G-hat(theta).
    pub fn gravity(&self, theta: &[f64], g: &mut [f64]) {
        self.layout.gravity.eval(&self.params, theta, g);
    }

    /// Smallest eigenvalue of M-hat over the positions `qs` (> 0: positive definite there).
    pub fn min_eig<'a>(&self, qs: impl Iterator<Item = &'a [f64]>) -> f64 {
        min_eig(&self.layout, &self.params, qs)
    }

    /// The identified servo's torque for error e = theta_d - theta and e' = theta_d' - theta'.
    pub fn torque(&self, e: &[f64], ed: &[f64], tau: &mut [f64]) {
        torque(&self.layout, &self.params, &self.zero, e, ed, tau)
    }

    /// x' = N_f(x; r): x = [theta; theta'], r = [theta_d; theta_d'] (2n each). Returns false
    /// (and leaves dx undefined) if M-hat is singular at theta.
    pub fn rate(&self, x: &[f64], r: &[f64], dx: &mut [f64]) -> bool {
        rate(&self.layout, &self.params, &self.zero, x, r, dx)
    }
}

/// Smallest eigenvalue of M-hat with parameters `p` over the positions `qs`. Allocation-free.
pub fn min_eig<'a>(layout: &Layout, p: &[f64], qs: impl Iterator<Item = &'a [f64]>) -> f64 {
    let mut m: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
    qs.map(|q| {
        inertia(layout, p, q, &mut m);
        sym_eig_range(layout.n, &m).0
    })
    .fold(f64::INFINITY, f64::min)
}

/// M-hat(theta) with parameters `p` into `m` (row-major, stride n), symmetric by
/// construction.
pub fn inertia(layout: &Layout, p: &[f64], theta: &[f64], m: &mut Mat) {
    let n = layout.n;
    let mut out = [0.0; 1];
    for ((a, b), net) in &layout.inertia {
        net.eval(p, theta, &mut out);
        m[a * n + b] = out[0];
        m[b * n + a] = out[0];
    }
}

/// M-hat into `m` and V-hat into `v` (see `Network::inertia_and_velocity`).
fn inertia_and_velocity(
    layout: &Layout,
    p: &[f64],
    theta: &[f64],
    qd: &[f64],
    m: &mut Mat,
    v: &mut [f64],
) {
    if layout.counts.velocity == 0 {
        christoffel(layout, p, theta, qd, m, v);
    } else {
        inertia(layout, p, theta, m);
        velocity(layout, p, theta, qd, v);
    }
}

pub(crate) fn velocity(layout: &Layout, p: &[f64], theta: &[f64], qd: &[f64], v: &mut [f64]) {
    if layout.counts.velocity == 0 {
        let mut m: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
        return christoffel(layout, p, theta, qd, &mut m, v);
    }
    let n = layout.n;
    let mut coef = [0.0; MAX_JOINTS * (MAX_JOINTS + 1) / 2 + MAX_JOINTS];
    for (i, net) in layout.velocity.iter().enumerate() {
        net.eval(p, theta, &mut coef);
        let mut k = 0;
        let mut vi = 0.0;
        for a in 0..n {
            for b in a + 1..n {
                vi += coef[k] * qd[a] * qd[b];
                k += 1;
            }
        }
        for a in 0..n {
            vi += coef[k + a] * qd[a] * qd[a];
        }
        v[i] = vi;
    }
}

/// V-hat from M-hat's Christoffel symbols (no velocity network, `RbfCounts::velocity` = 0):
///   V_i = sum_jk (d_k M_ij - 1/2 d_i M_jk) qd_j qd_k = (M-hat' qd)_i - 1/2 qd^T (d_i M-hat) qd,
/// so that the skew symmetry of eq. 3 holds by construction: qd^T V = 1/2 qd^T M-hat' qd. It
/// ties V-hat to M-hat, which the data then see through both; with the velocity network free,
/// a joint whose inertia does not couple to the others' could be scaled on its own, and no
/// torque-free data would tell. M-hat, computed on the way, goes into `m`.
fn christoffel(layout: &Layout, p: &[f64], theta: &[f64], qd: &[f64], m: &mut Mat, v: &mut [f64]) {
    let n = layout.n;
    let mut mdot: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
    let mut half = [0.0; MAX_JOINTS];
    let mut grad = [0.0; MAX_JOINTS];
    for ((a, b), net) in &layout.inertia {
        let value = net.value_and_gradient(p, theta, &mut grad);
        m[a * n + b] = value;
        m[b * n + a] = value;
        let d: f64 = grad[..n].iter().zip(qd).map(|(g, v)| g * v).sum();
        mdot[a * n + b] = d;
        mdot[b * n + a] = d;
        // qd^T (d_i M) qd counts an off-diagonal entry twice.
        let w = (if a == b { 0.5 } else { 1.0 }) * qd[*a] * qd[*b];
        for (h, g) in half[..n].iter_mut().zip(&grad) {
            *h += g * w;
        }
    }
    for i in 0..n {
        let md: f64 = (0..n).map(|b| mdot[i * n + b] * qd[b]).sum();
        v[i] = md - half[i];
    }
}

/// The servo's torque; `zero` = `servo_zero(layout, p)`.
pub(crate) fn torque(
    layout: &Layout,
    p: &[f64],
    zero: &ServoZero,
    e: &[f64],
    ed: &[f64],
    tau: &mut [f64],
) {
    let mut out = [0.0; 1];
    let mut at = |net: &SubNet, y: f64| {
        net.eval(p, &[y], &mut out);
        out[0]
    };
    if let Some(g) = layout.gains {
        for j in 0..layout.n {
            tau[j] = p[g + 2 * j] * e[j] + p[g + 2 * j + 1] * ed[j];
        }
        return;
    }
    for (j, [pn, dn]) in layout.torque.iter().enumerate() {
        tau[j] = (at(pn, e[j]) - zero[2 * j]) + (at(dn, ed[j]) - zero[2 * j + 1]);
    }
}

/// The right-hand side of M-hat theta'' = tau-hat(r - x) - V-hat - G-hat at x = [theta;
/// theta'] under reference r, into `f`, and M-hat into `m`; `zero` = `servo_zero(layout, p)`.
pub fn net_force(
    layout: &Layout,
    p: &[f64],
    zero: &ServoZero,
    x: &[f64],
    r: &[f64],
    m: &mut Mat,
    f: &mut [f64],
) {
    servo_torque(layout, p, zero, x, r, f);
    arm_terms(layout, p, x, m, f);
}

/// The servo's torque at x = [theta; theta'] under reference r into `f`.
fn servo_torque(layout: &Layout, p: &[f64], zero: &ServoZero, x: &[f64], r: &[f64], f: &mut [f64]) {
    let n = layout.n;
    let mut e = [0.0; MAX_JOINTS];
    let mut ed = [0.0; MAX_JOINTS];
    for j in 0..n {
        e[j] = r[j] - x[j];
        ed[j] = r[n + j] - x[n + j];
    }
    torque(layout, p, zero, &e, &ed, f);
}

/// At x = [theta; theta']: M-hat(theta) into `m`, and f <- f - V-hat(theta, theta') -
/// G-hat(theta).
fn arm_terms(layout: &Layout, p: &[f64], x: &[f64], m: &mut Mat, f: &mut [f64]) {
    let n = layout.n;
    let (theta, qd) = x.split_at(n);
    let mut v = [0.0; MAX_JOINTS];
    inertia_and_velocity(layout, p, &theta[..n], qd, m, &mut v);
    let mut g = [0.0; MAX_JOINTS];
    layout.gravity.eval(p, theta, &mut g);
    for j in 0..n {
        f[j] -= v[j] + g[j];
    }
}

/// N_f's theta'' for a given joint torque: tau <- M-hat^-1 (tau - V-hat - G-hat) at x = [theta;
/// theta'], in place. False (tau undefined) if M-hat is singular at theta.
pub fn acceleration(layout: &Layout, p: &[f64], x: &[f64], tau: &mut [f64]) -> bool {
    let mut m = [0.0; MAX_JOINTS * MAX_JOINTS];
    arm_terms(layout, p, x, &mut m, tau);
    solve(layout.n, &mut m, tau)
}

/// N_f; `zero` = `servo_zero(layout, p)`.
pub fn rate(
    layout: &Layout,
    p: &[f64],
    zero: &ServoZero,
    x: &[f64],
    r: &[f64],
    dx: &mut [f64],
) -> bool {
    let n = layout.n;
    let mut rhs = [0.0; MAX_JOINTS];
    servo_torque(layout, p, zero, x, r, &mut rhs);
    dx[..n].copy_from_slice(&x[n..2 * n]);
    acceleration(layout, p, x, &mut rhs[..n]) && {
        dx[n..2 * n].copy_from_slice(&rhs[..n]);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn random_net(n: usize, seed: u64) -> Network {
        let layout = Layout::new(n, RbfCounts::paper(n));
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let params = (0..layout.len).map(|_| rng.gen_range(-1.0..1.0)).collect();
        Network::new(layout, params)
    }

    #[test]
    fn layout_counts_for_three_joints() {
        let l = Layout::new(3, RbfCounts::paper(3));
        // Torque 6 x 3 x (1+1+1); inertia 6 x 10 x (3+1+1); velocity 3 x 3 x (3+1+6);
        // gravity 3 x (3+1+3).
        assert_eq!(l.len, 54 + 300 + 90 + 21);
        assert_eq!(l.subnets().count(), 6 + 6 + 3 + 1);
        let last = l.subnets().last().unwrap().1;
        assert_eq!(last.offset + last.len(), l.len);
    }

    #[test]
    fn m_hat_is_symmetric_for_any_parameters() {
        for seed in 0..20 {
            let net = random_net(3, seed);
            let mut m = [0.0; MAX_JOINTS * MAX_JOINTS];
            net.inertia(&[0.3, -0.7, 1.1], &mut m);
            for a in 0..3 {
                for b in 0..3 {
                    assert_eq!(m[a * 3 + b], m[b * 3 + a]);
                }
            }
        }
    }

    #[test]
    fn one_rbf_by_hand() {
        // c = [1, 2], s = 0.5, W = [3, -1]: at y = [1.5, 2], phi = exp(-0.25 / 0.25) = e^-1.
        let s = SubNet {
            inputs: 2,
            outputs: 2,
            rbfs: 1,
            offset: 1,
        };
        let p = [9.0, 1.0, 2.0, 0.5, 3.0, -1.0];
        let mut out = [0.0; 2];
        s.eval(&p, &[1.5, 2.0], &mut out);
        let e = (-1.0f64).exp();
        assert!((out[0] - 3.0 * e).abs() < 1e-10 && (out[1] + e).abs() < 1e-10);
    }

    #[test]
    fn velocity_network_is_eqs_8_to_10() {
        // V_i = B_i [qd_a qd_b] + C_i [qd^2] with the coefficient outputs read back by hand.
        let net = random_net(3, 7);
        let theta = [0.2, 0.4, -0.3];
        let qd = [0.5, -1.5, 2.0];
        let mut v = [0.0; 3];
        net.velocity(&theta, &qd, &mut v);
        for (i, sub) in net.layout.velocity.iter().enumerate() {
            let mut c = [0.0; 6];
            sub.eval(net.params(), &theta, &mut c);
            let want = c[0] * qd[0] * qd[1]
                + c[1] * qd[0] * qd[2]
                + c[2] * qd[1] * qd[2]
                + c[3] * qd[0] * qd[0]
                + c[4] * qd[1] * qd[1]
                + c[5] * qd[2] * qd[2];
            assert!((v[i] - want).abs() < 1e-12);
        }
    }

    #[test]
    fn christoffel_v_hat_is_skew_symmetric_and_matches_finite_differences() {
        // No velocity network: V-hat = M-hat' qd - 1/2 d/dq (qd^T M-hat qd), checked by central
        // differences of M-hat itself, and eq. 3's consequence qd^T V = 1/2 qd^T M-hat' qd.
        let counts = RbfCounts {
            velocity: 0,
            ..RbfCounts::paper(3)
        };
        let layout = Layout::new(3, counts);
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let params: Vec<f64> = (0..layout.len).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let net = Network::new(layout, params);
        let q = [0.3, -0.4, 0.9];
        let qd = [0.7, -1.1, 0.4];
        let mut v = [0.0; 3];
        net.velocity(&q, &qd, &mut v);
        let h = 1e-6;
        let at = |dq: &[f64; 3]| {
            let mut m = [0.0; MAX_JOINTS * MAX_JOINTS];
            net.inertia(&[q[0] + dq[0], q[1] + dq[1], q[2] + dq[2]], &mut m);
            m
        };
        let quad = |m: &Mat| -> f64 {
            (0..3)
                .flat_map(|a| (0..3).map(move |b| (a, b)))
                .map(|(a, b)| qd[a] * m[a * 3 + b] * qd[b])
                .sum()
        };
        // M-hat' = (M(q + h qd) - M(q - h qd)) / 2h.
        let (fwd, back) = (
            at(&[h * qd[0], h * qd[1], h * qd[2]]),
            at(&[-h * qd[0], -h * qd[1], -h * qd[2]]),
        );
        let mdot: Vec<f64> = (0..9).map(|k| (fwd[k] - back[k]) / (2.0 * h)).collect();
        for i in 0..3 {
            let mut e = [0.0; 3];
            e[i] = h;
            let grad_i = (quad(&at(&e)) - quad(&at(&[-e[0], -e[1], -e[2]]))) / (2.0 * h);
            let want: f64 = (0..3).map(|b| mdot[i * 3 + b] * qd[b]).sum::<f64>() - 0.5 * grad_i;
            assert!(
                (v[i] - want).abs() < 1e-6 * (1.0 + want.abs()),
                "V_{i}: {} vs {want}",
                v[i]
            );
        }
        let power: f64 = (0..3).map(|i| qd[i] * v[i]).sum();
        let half_mdot: f64 = 0.5
            * (0..3)
                .flat_map(|a| (0..3).map(move |b| (a, b)))
                .map(|(a, b)| qd[a] * mdot[a * 3 + b] * qd[b])
                .sum::<f64>();
        assert!(
            (power - half_mdot).abs() < 1e-6 * (1.0 + power.abs()),
            "{power} vs {half_mdot}"
        );
    }

    #[test]
    fn one_pass_m_hat_and_v_hat_equal_the_separate_calls_bit_for_bit() {
        // The controller's cycle and N_f take M-hat and V-hat from `inertia_and_velocity`; with
        // and without a velocity network it must be `inertia` and `velocity` exactly.
        for velocity in [0, 3] {
            let layout = Layout::new(
                3,
                RbfCounts {
                    velocity,
                    ..RbfCounts::paper(3)
                },
            );
            let mut rng = rand::rngs::StdRng::seed_from_u64(5);
            let params = (0..layout.len).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let net = Network::new(layout, params);
            let (q, qd) = ([0.4, -0.2, 1.0], [-0.6, 0.9, 0.3]);
            let (mut m1, mut m2) = (
                [0.0; MAX_JOINTS * MAX_JOINTS],
                [0.0; MAX_JOINTS * MAX_JOINTS],
            );
            let (mut v1, mut v2) = ([0.0; 3], [0.0; 3]);
            net.inertia(&q, &mut m1);
            net.velocity(&q, &qd, &mut v1);
            net.inertia_and_velocity(&q, &qd, &mut m2, &mut v2);
            assert_eq!(
                m1.map(f64::to_bits),
                m2.map(f64::to_bits),
                "velocity RBFs {velocity}"
            );
            assert_eq!(
                v1.map(f64::to_bits),
                v2.map(f64::to_bits),
                "velocity RBFs {velocity}"
            );
        }
    }

    #[test]
    fn rate_solves_the_arm_equation() {
        // M-hat theta'' = tau - V - G, checked by multiplying back.
        let net = random_net(3, 3);
        let x = [0.1, 0.5, -1.0, 0.3, -0.2, 0.4];
        let r = [0.2, 0.4, -0.9, 0.0, 0.1, 0.3];
        let mut dx = [0.0; 6];
        assert!(net.rate(&x, &r, &mut dx));
        assert_eq!(&dx[..3], &x[3..]);
        let (mut m, mut tau, mut v, mut g) = ([0.0; 64], [0.0; 3], [0.0; 3], [0.0; 3]);
        net.inertia(&x[..3], &mut m);
        let e: Vec<f64> = (0..3).map(|j| r[j] - x[j]).collect();
        let ed: Vec<f64> = (0..3).map(|j| r[3 + j] - x[3 + j]).collect();
        net.torque(&e, &ed, &mut tau);
        net.velocity(&x[..3], &x[3..], &mut v);
        net.gravity(&x[..3], &mut g);
        for i in 0..3 {
            let mq: f64 = (0..3).map(|k| m[i * 3 + k] * dx[3 + k]).sum();
            assert!((mq - (tau[i] - v[i] - g[i])).abs() < 1e-9 * (1.0 + mq.abs()));
        }
    }
}
