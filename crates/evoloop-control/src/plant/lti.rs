//! A linear time-invariant plant of the user's own: state-space matrices (A, B, C, D) or a
//! transfer function (num, den), continuous or discrete, written in the scenario or in a model
//! file (JSON as python-control or MATLAB export it, or TOML).
//!
//! A continuous model is discretised exactly for a zero-order hold at the control period:
//! exp([[A, B], [0, 0]] T) = [[Phi, Gamma], [0, I]] (nalgebra's Padé scaling-and-squaring
//! exponential), so a lockstep run steps x_{k+1} = Phi x_k + Gamma u_k with no integration
//! error. A period split where a command arrives (realtime) is integrated from x' = A x + B u
//! with RK4 at `plant.step`. A discrete model (`dt`, which must be the control period) and an
//! input delay (whole periods) move once a period, so they run in lockstep only.
//!
//! The measured output at sample k is y_k = C x_k + D v_{k-1}, where v is the input that reached
//! the plant over the period before: the sample is taken before the controller answers it, so
//! a direct feedthrough acts through the input in force at that instant, not the one it causes.
//!
//! Simulated state: [x (n) | the delay line (m per period of delay) | v (m)].

use super::{LinearModel, Plant, PlantConfig, PlantContext, ScalarInput};
use crate::check::{Check, ConfigError};
use crate::plant::linear::{norm_period, MAX_LINEAR_STATES, MAX_NORM_PERIOD};
use crate::{MAX_JOINTS, MAX_STATES};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;


/// The most periods of input delay (the delay line is part of the state, `MAX_STATES`).
pub const MAX_DELAY_PERIODS: usize = 24;

/// The validated `[plant.lti]`, also the simulated model. Matrices are row-major.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LtiSpec {
    /// States, inputs, outputs.
    pub n: usize,
    /// The number of inputs.
    pub m: usize,
    /// The number of measured outputs.
    pub p: usize,
    /// As configured (continuous, or discrete at `dt`), after a transfer function's
    /// realisation (controllable canonical form, as SciPy's `tf2ss`).
    pub a: Vec<f64>,
    /// B, n x m.
    pub b: Vec<f64>,
    /// C, p x n.
    pub c: Vec<f64>,
    /// D, p x m: the direct feedthrough, acting through the input of the period before.
    pub d: Vec<f64>,
    /// A discrete model's sample time (the control period); None for a continuous one.
    pub dt: Option<f64>,
    /// The control period and the model's exact zero-order-hold discretisation at it.
    pub period: f64,
    /// Phi = exp(A T), n x n (A itself for a discrete model).
    pub phi: Vec<f64>,
    /// Gamma, n x m: the effect of an input held over one period (B itself for a discrete model).
    pub gamma: Vec<f64>,
    /// Input delay, whole control periods.
    pub delay: usize,
    /// The initial state, n values (default 0).
    pub x0: Vec<f64>,
    /// The actuator's range per input (the command is clipped to it).
    pub u_min: Vec<f64>,
    /// The upper end of each input's range, above its `u_min` (default unbounded).
    pub u_max: Vec<f64>,
    /// The model file the matrices came from, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// Changes of A and B in operation, in time order (`[[plant.lti.change]]`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub changes: Vec<LtiChange>,
}

/// A change of the plant in operation (a load attached, a gear changed): from `at` on it runs
/// with these A and B, its state carrying over (C and D stay). Written in the model's own
/// state coordinates, so states with a physical meaning stay continuous across it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LtiChange {
    /// When the change takes effect, s of plant time (from the period starting then).
    pub at: f64,
    /// A from then on, n x n (the one before where the change gives none).
    pub a: Vec<f64>,
    /// B from then on, n x m (the one before where the change gives none).
    pub b: Vec<f64>,
    /// Their zero-order-hold discretisation at the control period.
    pub phi: Vec<f64>,
    /// Gamma of that discretisation, n x m (B itself for a discrete model).
    pub gamma: Vec<f64>,
}

/// The model in force at one instant: (A, B) and (Phi, Gamma).
struct Phase<'a> {
    a: &'a [f64],
    b: &'a [f64],
    phi: &'a [f64],
    gamma: &'a [f64],
}

/// y = Mx (+ y), M rows x cols row-major.
fn mul_add(m: &[f64], rows: usize, x: &[f64], y: &mut [f64]) {
    let cols = x.len();
    for (i, yi) in y.iter_mut().enumerate().take(rows) {
        *yi += m[i * cols..(i + 1) * cols]
            .iter()
            .zip(x)
            .map(|(a, b)| a * b)
            .sum::<f64>();
    }
}

impl LtiSpec {
    fn delay_len(&self) -> usize {
        self.m * self.delay
    }

    /// y = C x + D v.
    pub fn output_with(&self, x: &[f64], v: &[f64], y: &mut [f64]) {
        y[..self.p].fill(0.0);
        mul_add(&self.c, self.p, &x[..self.n], y);
        mul_add(&self.d, self.p, &v[..self.m], y);
    }

    /// The command as the actuator applies it (clipped to its range), on the stack.
    fn clipped(&self, u: &[f64]) -> [f64; MAX_JOINTS] {
        let mut out = [0.0; MAX_JOINTS];
        for (i, o) in out.iter_mut().enumerate().take(self.m) {
            *o = u[i].clamp(self.u_min[i], self.u_max[i]);
        }
        out
    }

    /// The model in force at time `t` (a change takes effect at the period starting at its
    /// time, to within a millionth of a period of accumulated rounding).
    fn phase(&self, t: f64) -> Phase<'_> {
        // Plant time is a running sum of periods: its rounding reaches 1e-11 s within a minute
        // at 1 ms, so the slack is a millionth of a period.
        let slack = 1e-6 * self.period;
        match self.changes.iter().rev().find(|c| t + slack >= c.at) {
            Some(c) => Phase {
                a: &c.a,
                b: &c.b,
                phi: &c.phi,
                gamma: &c.gamma,
            },
            None => Phase {
                a: &self.a,
                b: &self.b,
                phi: &self.phi,
                gamma: &self.gamma,
            },
        }
    }

    /// A continuous single-input single-output model from a transfer function (descending
    /// powers), realised and discretised as `[plant.lti]` does at `period`, with the actuator's
    /// range: the model the general indirect scheme tunes on.
    ///
    /// # Errors
    ///
    /// The transfer function is refused as `[plant.lti]` refuses it (`num`, `den`: improper,
    /// not finite, a leading zero ...), or it cannot be held between samples at `period`; the
    /// error's file is `model`.
    pub fn from_transfer_function(
        num: &[f64],
        den: &[f64],
        period: f64,
        u_range: (f64, f64),
    ) -> Result<LtiSpec, ConfigError> {
        let src = Source {
            check: Check::new("model".as_ref()),
            prefix: "",
        };
        let r = transfer_function(Some(num), Some(den), &src)?;
        let (phi, gamma) = discretised(&r.a, &r.b, r.n, r.m, period, false)
            .or_else(|reason| src.check.fail("period", reason))?;
        Ok(LtiSpec {
            x0: vec![0.0; r.n],
            n: r.n,
            m: 1,
            p: 1,
            a: r.a,
            b: r.b,
            c: r.c,
            d: r.d,
            dt: None,
            period,
            phi,
            gamma,
            delay: 0,
            u_min: vec![u_range.0],
            u_max: vec![u_range.1],
            file: None,
            changes: Vec::new(),
        })
    }

    /// The configured (t = 0) model's transfer function (num, den), descending powers, den
    /// monic: the characteristic polynomial by Faddeev-LeVerrier, the numerator from the Markov
    /// parameters (b = a(s) H(s), truncated). Continuous, single input and output only.
    pub fn transfer_function(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        if self.m != 1 || self.p != 1 || self.dt.is_some() {
            return None;
        }
        let n = self.n;
        let a = DMatrix::from_row_slice(n, n, &self.a);
        // den[k] is the coefficient of s^(n-k); den[0] = 1.
        let mut den = vec![1.0; n + 1];
        let mut m = DMatrix::<f64>::zeros(n, n);
        for k in 1..=n {
            m = &a * &m + DMatrix::identity(n, n) * den[k - 1];
            den[k] = -(&a * &m).trace() / k as f64;
        }
        let h = self.markov_parameters(&self.a, &self.b);
        let num = (0..=n)
            .map(|j| (0..=j).map(|i| den[i] * h[j - i]).sum())
            .collect();
        Some((num, den))
    }

    /// The input gain at time `t`: the first Markov parameter that is not zero (D, C B,
    /// C A B, ...), which is a monic transfer function's leading numerator coefficient. Single
    /// input and output only.
    pub fn input_gain_at(&self, t: f64) -> Option<f64> {
        if self.m != 1 || self.p != 1 {
            return None;
        }
        let ph = self.phase(t);
        self.markov_parameters(ph.a, ph.b)
            .into_iter()
            .find(|h| *h != 0.0)
    }

    /// h_0 = D, h_j = C A^(j-1) B for j = 1..=n, of the single-input single-output model with
    /// these A and B.
    fn markov_parameters(&self, a: &[f64], b: &[f64]) -> Vec<f64> {
        let mut h = vec![self.d[0]];
        let mut v = b.to_vec();
        for _ in 0..self.n {
            h.push(self.c.iter().zip(&v).map(|(c, x)| c * x).sum());
            let mut next = vec![0.0; self.n];
            mul_add(a, self.n, &v, &mut next);
            v = next;
        }
        h
    }

    /// One control period with the (clipped) command `u` under the model of time `t`: exact,
    /// allocation-free.
    fn step_period(&self, t: f64, s: &mut [f64], u: &[f64]) {
        let ph = self.phase(t);
        let (n, m, dl) = (self.n, self.m, self.delay_len());
        let (x, rest) = s.split_at_mut(n);
        let (line, v) = rest.split_at_mut(dl);
        // The input reaching the plant this period: the delay line's head, or u itself.
        let mut reach = [0.0; MAX_JOINTS];
        reach[..m].copy_from_slice(if dl > 0 { &line[..m] } else { &u[..m] });
        let mut next = [0.0; MAX_STATES];
        mul_add(ph.phi, n, x, &mut next);
        mul_add(ph.gamma, n, &reach[..m], &mut next);
        x.copy_from_slice(&next[..n]);
        if dl > 0 {
            line.copy_within(m.., 0);
            line[dl - m..].copy_from_slice(&u[..m]);
        }
        v[..m].copy_from_slice(&reach[..m]);
    }

    /// Whole control periods in `dt`, if it is (to 1e-9 of a period) a whole number of them.
    fn periods_in(&self, dt: f64) -> Option<usize> {
        let k = (dt / self.period).round();
        ((dt - k * self.period).abs() <= 1e-9 * self.period && k >= 1.0).then_some(k as usize)
    }

    /// Moves once a period only (discrete, or delayed).
    fn periodic_only(&self) -> bool {
        self.dt.is_some() || self.delay > 0
    }

    /// The sampled single-input single-output model state feedback is checked against, over
    /// z = [x; the delay line] (what the law reads of the state).
    fn sampled_model(&self) -> Option<LinearModel> {
        let nz = self.n + self.delay;
        if self.m != 1 || self.p != 1 || nz > MAX_LINEAR_STATES {
            return None;
        }
        let n = self.n;
        let mut a = vec![0.0; nz * nz];
        let mut b = vec![0.0; nz];
        let mut c = vec![0.0; nz];
        let mut f = vec![0.0; nz];
        for i in 0..n {
            a[i * nz..i * nz + n].copy_from_slice(&self.phi[i * n..(i + 1) * n]);
        }
        c[..n].copy_from_slice(&self.c);
        let g = if self.delay == 0 {
            b[..n].copy_from_slice(&self.gamma);
            1.0
        } else {
            // x+ = Phi x + Gamma w_1; w_i+ = w_{i+1}; w_d+ = u; the plant receives w_1.
            for i in 0..n {
                a[i * nz + n] = self.gamma[i];
            }
            for i in n..nz - 1 {
                a[i * nz + i + 1] = 1.0;
            }
            b[nz - 1] = 1.0;
            f[n] = 1.0;
            0.0
        };
        Some(LinearModel::sampled(self.period, &a, &b, &c, self.d[0], &f, g))
    }
}

impl Plant for LtiSpec {
    fn n_states(&self) -> usize {
        self.n + self.delay_len() + self.m
    }
    fn n_inputs(&self) -> usize {
        self.m
    }
    fn n_outputs(&self) -> usize {
        self.p
    }
    fn n_joints(&self) -> usize {
        self.p
    }
    /// x' = A x + B v (v, the input in force, is part of the state; RK4 leaves it).
    fn derivative(&self, t: f64, s: &[f64], _u: &[f64], ds: &mut [f64]) {
        ds.fill(0.0);
        let at = self.n + self.delay_len();
        let v = &s[at..at + self.m];
        let ph = self.phase(t);
        mul_add(ph.a, self.n, &s[..self.n], ds);
        mul_add(ph.b, self.n, v, ds);
    }
    fn output(&self, s: &[f64], y: &mut [f64]) {
        self.output_with(s, &s[self.n + self.delay_len()..], y);
    }
    /// The outputs and, for a continuous model, their rate C (A x + B v); 0 for a discrete one.
    /// (The rate is the configured model's: `joints` knows no time, and it is for display.)
    fn joints(&self, s: &[f64], q: &mut [f64], qd: &mut [f64]) {
        self.output(s, q);
        qd[..self.p].fill(0.0);
        if self.dt.is_none() {
            let mut dx = [0.0; MAX_STATES];
            self.derivative(f64::NEG_INFINITY, s, &[], &mut dx[..s.len()]);
            mul_add(&self.c, self.p, &dx[..self.n], qd);
        }
    }
    fn initial_state(&self, s: &mut [f64]) {
        s.fill(0.0);
        s[..self.n].copy_from_slice(&self.x0);
    }
    /// Whole periods step exactly; any other span of a continuous model is integrated (RK4)
    /// with the command recorded as the input in force. A discrete or delayed model moves the
    /// whole periods in `dt` (the configuration keeps it to lockstep, where every span is one).
    fn map(&self, t: f64, s: &mut [f64], u: &[f64], dt: f64) -> bool {
        let u = self.clipped(u);
        let at = |i: usize| t + i as f64 * self.period;
        match self.periods_in(dt) {
            Some(k) => (0..k).for_each(|i| self.step_period(at(i), s, &u)),
            None if self.periodic_only() => {
                debug_assert!(false, "a discrete or delayed lti plant advanced by {dt} s");
                let k = (dt / self.period).round() as usize;
                (0..k).for_each(|i| self.step_period(at(i), s, &u));
            }
            None => {
                let at = self.n + self.delay_len();
                s[at..at + self.m].copy_from_slice(&u[..self.m]);
                return false;
            }
        }
        true
    }
}

impl PlantConfig for LtiSpec {
    fn build(&self) -> Box<dyn Plant> {
        Box::new(self.clone())
    }
    fn linear_model(&self) -> Option<LinearModel> {
        self.sampled_model()
    }
    /// A single input's range (for a plant with one input and one output); it holds at 0
    /// (clipped into the range).
    fn scalar_input(&self) -> Option<ScalarInput> {
        (self.m == 1 && self.p == 1).then(|| ScalarInput::holding_zero(self.u_min[0], self.u_max[0]))
    }
    /// With changes configured: the input gain (`input_gain_at`), what the general indirect
    /// scheme's estimate is judged against.
    fn varying_parameter(&self, t: f64) -> Option<f64> {
        if self.changes.is_empty() {
            return None;
        }
        self.input_gain_at(t)
    }
    fn first_change(&self) -> Option<f64> {
        self.changes.first().map(|c| c.at)
    }
    fn realtime_refusal(&self) -> Option<String> {
        let what = match (self.dt.is_some(), self.delay > 0) {
            (true, _) => "a discrete-time model (plant.lti.dt)",
            (false, true) => "an input delay (plant.lti.input_delay)",
            (false, false) => return None,
        };
        Some(format!(
            "{what} moves once a control period, and realtime splits a period where a command \
             arrives: run it in lockstep, or give a continuous model without delay"
        ))
    }
}

// ---------------------------------------------------------------- configuration

/// A matrix as written: a number, one row (a column for B, a row for C), or rows.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum Matrix {
    /// A number: a 1 x 1 matrix.
    Scalar(f64),
    /// One list: a column for B, a row otherwise.
    Flat(Vec<f64>),
    /// A list of rows, all of the same length.
    Rows(Vec<Vec<f64>>),
}

/// The model's keys, in `[plant.lti]` or in the model file `file` names.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelKeys {
    a: Option<Matrix>,
    b: Option<Matrix>,
    c: Option<Matrix>,
    d: Option<Matrix>,
    num: Option<Vec<f64>>,
    den: Option<Vec<f64>>,
    dt: Option<f64>,
}

impl ModelKeys {
    /// Each key and whether it is given, in declaration order: the state space's four, the
    /// transfer function's two, then `dt`.
    fn present(&self) -> [(&'static str, bool); 7] {
        [
            ("a", self.a.is_some()),
            ("b", self.b.is_some()),
            ("c", self.c.is_some()),
            ("d", self.d.is_some()),
            ("num", self.num.is_some()),
            ("den", self.den.is_some()),
            ("dt", self.dt.is_some()),
        ]
    }
}

/// The `[plant.lti]` keys: the model's (as `ModelKeys`, which a model file holds instead:
/// repeated here because serde's `flatten` cannot refuse unknown keys) and the plant's.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    /// A model file (JSON or TOML) holding the model's keys instead.
    file: Option<PathBuf>,
    a: Option<Matrix>,
    b: Option<Matrix>,
    c: Option<Matrix>,
    d: Option<Matrix>,
    num: Option<Vec<f64>>,
    den: Option<Vec<f64>>,
    dt: Option<f64>,
    /// s, whole control periods.
    input_delay: Option<f64>,
    x0: Option<Vec<f64>>,
    u_min: Option<Vec<f64>>,
    u_max: Option<Vec<f64>>,
    /// Changes in operation: `[[plant.lti.change]]` with `at` and a new `a` and/or `b`.
    change: Option<Vec<ChangeTable>>,
}

/// One `[[plant.lti.change]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChangeTable {
    at: f64,
    a: Option<Matrix>,
    b: Option<Matrix>,
}

/// Where the model's keys were read and how to name them in an error.
struct Source {
    check: Check,
    prefix: &'static str,
}

impl Source {
    fn key(&self, k: &str) -> String {
        format!("{}{k}", self.prefix)
    }
    fn fail<T>(&self, k: &str, reason: impl Into<String>) -> Result<T, ConfigError> {
        self.check.fail(&self.key(k), reason)
    }
}

/// A realised model: (A, B, C, D) row-major and its sizes.
struct Realised {
    n: usize,
    m: usize,
    p: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    d: Vec<f64>,
}

/// Validate `[plant.lti]`: the model (state space or transfer function, in the table or the file it
/// names; a discrete one at the control period), the input delay, at most `MAX_STATES` simulated
/// states, one reference per output, the initial state, the input range and the changes. Fails when
/// the table is missing, or the model is malformed or too fast to discretise at the period.
pub fn validate(t: Option<Table>, check: &Check, cx: &PlantContext) -> Result<LtiSpec, ConfigError> {
    let Some(mut t) = t else {
        return check.fail(
            "plant.lti",
            "missing table [plant.lti]: the model's a, b, c (and d), or num and den, or a file",
        );
    };
    let (keys, src, file) = model_keys(&mut t, check)?;
    let dt = match keys.dt {
        Some(dt) => Some(discrete_at(&src, dt, cx.period)?),
        None => None,
    };
    let r = realise(&keys, &src)?;
    let delay = input_delay(check, t.input_delay.unwrap_or(0.0), cx.period)?;
    let states = r.n + r.m * delay + r.m;
    if states > MAX_STATES {
        return check.fail(
            "plant.lti",
            format!(
                "{} states, {} inputs and a delay of {delay} periods make {states} simulated \
                 states; at most {MAX_STATES}",
                r.n, r.m
            ),
        );
    }
    super::one_reference_per_output(check, cx.reference, r.p)?;
    let x0 = t.x0.unwrap_or_else(|| vec![0.0; r.n]);
    check.finite_values("plant.lti.x0", &x0, r.n, " (one per state)")?;
    let (u_min, u_max) = super::input_range(check, "plant.lti", t.u_min, t.u_max, r.m)?;
    let (phi, gamma) = discretised(&r.a, &r.b, r.n, r.m, cx.period, dt.is_some())
        .or_else(|why| src.fail("a", why))?;
    let changes = changes(t.change.take().unwrap_or_default(), check, &r, dt.is_some(), cx.period)?;
    Ok(LtiSpec {
        n: r.n,
        m: r.m,
        p: r.p,
        a: r.a,
        b: r.b,
        c: r.c,
        d: r.d,
        dt,
        period: cx.period,
        phi,
        gamma,
        delay,
        x0,
        u_min,
        u_max,
        file,
        changes,
    })
}

/// The validated `[[plant.lti.change]]` list: times increasing and positive, matrices the
/// model's sizes (a missing one stays as it was), each discretised as the model is.
fn changes(
    raw: Vec<ChangeTable>,
    check: &Check,
    r: &Realised,
    discrete: bool,
    period: f64,
) -> Result<Vec<LtiChange>, ConfigError> {
    let mut out: Vec<LtiChange> = Vec::with_capacity(raw.len());
    for (i, c) in raw.into_iter().enumerate() {
        let key = format!("plant.lti.change[{i}]");
        let src = Source {
            check: Check::new(&check.file),
            prefix: "",
        };
        let at = check.range(&format!("{key}.at"), c.at, 0.0, 1e9)?;
        if out.last().is_some_and(|p| at <= p.at) {
            return check.fail(&format!("{key}.at"), "change times must increase");
        }
        let (prev_a, prev_b) = out.last().map_or((&r.a, &r.b), |p| (&p.a, &p.b));
        let (n, m) = (r.n, r.m);
        // A given matrix, of the model's size; a missing one stays as it was.
        let read = |name: &str, given: &Option<Matrix>, prev: &Vec<f64>, size, flat_is_column| {
            let Some(given) = given else {
                return Ok(prev.clone());
            };
            let k = format!("{key}.{name}");
            let (rows, cols, v) = shaped(&src, &k, given, flat_is_column)?;
            expect_size(&src, &k, (rows, cols), size, "the model's, its size")?;
            Ok(v)
        };
        let a = read("a", &c.a, prev_a, (n, n), false)?;
        let b = read("b", &c.b, prev_b, (n, m), true)?;
        if c.a.is_none() && c.b.is_none() {
            return check.fail(&key, "a change needs a new a, b or both");
        }
        let (phi, gamma) = discretised(&a, &b, n, m, period, discrete)
            .or_else(|why| check.fail(&format!("{key}.a"), why))?;
        out.push(LtiChange { at, a, b, phi, gamma });
    }
    Ok(out)
}

/// The model's keys from the table, or from the file it names (then the table holds none).
fn model_keys(t: &mut Table, check: &Check) -> Result<(ModelKeys, Source, Option<PathBuf>), ConfigError> {
    let inline = ModelKeys {
        a: t.a.take(),
        b: t.b.take(),
        c: t.c.take(),
        d: t.d.take(),
        num: t.num.take(),
        den: t.den.take(),
        dt: t.dt.take(),
    };
    let Some(rel) = &t.file else {
        let src = Source {
            check: Check::new(&check.file),
            prefix: "plant.lti.",
        };
        return Ok((inline, src, None));
    };
    for (k, present) in inline.present() {
        check.unused(&format!("plant.lti.{k}"), present, "beside plant.lti.file, which holds the model")?;
    }
    let path = check.resolve(rel);
    let in_file = Check::new(&path);
    let text = evoloop_files::read_text(&path)
        .or_else(|e| check.fail("plant.lti.file", format!("cannot read {}: {e}", path.display())))?;
    let json = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let parsed = if json {
        evoloop_files::from_json::<ModelKeys>(&text)
    } else {
        evoloop_files::from_toml::<ModelKeys>(&text)
    };
    let keys = parsed.map_err(|p| ConfigError {
        file: path.clone(),
        key: p.key,
        reason: p.reason,
        line: p.line,
    })?;
    let src = Source {
        check: in_file,
        prefix: "",
    };
    Ok((keys, src, Some(path)))
}

fn discrete_at(src: &Source, dt: f64, period: f64) -> Result<f64, ConfigError> {
    let dt = src.check.positive(&src.key("dt"), dt)?;
    if (dt - period).abs() > 1e-9 * period {
        return src.fail(
            "dt",
            format!(
                "the model is sampled at {dt} s and the control period is {period} s: resample \
                 it (python-control's sample_system, MATLAB's d2d) or set timing.period"
            ),
        );
    }
    Ok(period)
}

/// (A, B, C, D) from the matrices, or a transfer function's controllable canonical form.
fn realise(k: &ModelKeys, src: &Source) -> Result<Realised, ConfigError> {
    let given = k.present();
    let state_space = given[..4].iter().any(|g| g.1);
    let transfer = given[4..6].iter().any(|g| g.1);
    match (state_space, transfer) {
        (true, true) => src.fail(
            "num",
            "give the state-space matrices (a, b, c, d) or a transfer function (num, den), not both",
        ),
        (false, false) => src.fail("a", "missing: the state-space a, b, c (and d), or num and den"),
        (false, true) => transfer_function(k.num.as_deref(), k.den.as_deref(), src),
        (true, false) => state_space_model(k, src),
    }
}

/// `m` as (rows, cols, row-major values), finite; a flat list is a column where `flat_is_column`.
fn shaped(
    src: &Source,
    key: &str,
    m: &Matrix,
    flat_is_column: bool,
) -> Result<(usize, usize, Vec<f64>), ConfigError> {
    let (rows, cols, v) = match m {
        Matrix::Scalar(x) => (1, 1, vec![*x]),
        Matrix::Flat(v) if flat_is_column => (v.len(), 1, v.clone()),
        Matrix::Flat(v) => (1, v.len(), v.clone()),
        Matrix::Rows(r) => {
            let cols = r.first().map_or(0, Vec::len);
            if let Some(i) = r.iter().position(|row| row.len() != cols) {
                return src.fail(
                    &format!("{key}[{i}]"),
                    format!("row {i} has {} values, row 0 has {cols}", r[i].len()),
                );
            }
            (r.len(), cols, r.concat())
        }
    };
    if rows == 0 || cols == 0 {
        return src.fail(key, "is empty");
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return src.fail(key, format!("entry {i} (row-major) is {}: must be finite", v[i]));
    }
    Ok((rows, cols, v))
}

fn expect_size(
    src: &Source,
    key: &str,
    got: (usize, usize),
    want: (usize, usize),
    why: &str,
) -> Result<(), ConfigError> {
    if got != want {
        return src.fail(
            key,
            format!(
                "is {} x {}, must be {} x {} ({why})",
                got.0, got.1, want.0, want.1
            ),
        );
    }
    Ok(())
}

fn state_space_model(k: &ModelKeys, src: &Source) -> Result<Realised, ConfigError> {
    let (a, b, c) = match (&k.a, &k.b, &k.c) {
        (Some(a), Some(b), Some(c)) => (a, b, c),
        _ => {
            let key = [("a", &k.a), ("b", &k.b), ("c", &k.c)]
                .iter()
                .find(|(_, m)| m.is_none())
                .map_or("a", |(key, _)| *key);
            return src.fail(key, "missing (a state-space model needs a, b and c; d defaults to 0)");
        }
    };
    if matches!(a, Matrix::Flat(v) if v.len() > 1) {
        return src.fail("a", "A is square: write it as a list of rows, [[a11, a12], [a21, a22]]");
    }
    let (n, na, a) = shaped(src, "a", a, false)?;
    expect_size(src, "a", (n, na), (n, n), "A is square")?;
    if n > MAX_STATES - 1 {
        return src.fail("a", format!("{n} states; at most {}", MAX_STATES - 1));
    }
    let (nb, m, b) = shaped(src, "b", b, true)?;
    expect_size(src, "b", (nb, m), (n, m), &format!("one row per state: A is {n} x {n}"))?;
    let (p, nc, c) = shaped(src, "c", c, false)?;
    expect_size(src, "c", (p, nc), (p, n), &format!("one column per state: A is {n} x {n}"))?;
    for (key, count, what) in [("b", m, "inputs"), ("c", p, "outputs")] {
        if count > MAX_JOINTS {
            return src.fail(key, format!("{count} {what}; at most {MAX_JOINTS}"));
        }
    }
    let d = match &k.d {
        None => vec![0.0; p * m],
        Some(Matrix::Scalar(x)) if *x == 0.0 => vec![0.0; p * m],
        Some(d) => {
            let flat_is_column = m == 1;
            let (pd, md, d) = shaped(src, "d", d, flat_is_column)?;
            expect_size(src, "d", (pd, md), (p, m), &format!("outputs x inputs: C has {p} rows, B {m} columns"))?;
            d
        }
    };
    Ok(Realised { n, m, p, a, b, c, d })
}

/// num/den (descending powers) to the controllable canonical form SciPy's `tf2ss` gives.
fn transfer_function(num: Option<&[f64]>, den: Option<&[f64]>, src: &Source) -> Result<Realised, ConfigError> {
    let (Some(num), Some(den)) = (num, den) else {
        let key = if num.is_none() { "num" } else { "den" };
        return src.fail(key, "missing: a transfer function needs num and den");
    };
    for (key, v) in [("num", num), ("den", den)] {
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return src.fail(&format!("{key}[{i}]"), format!("must be finite (got {})", v[i]));
        }
    }
    let den = &den[den.iter().position(|x| *x != 0.0).unwrap_or(den.len())..];
    let num = &num[num.iter().position(|x| *x != 0.0).unwrap_or(num.len())..];
    if den.len() < 2 {
        return src.fail("den", "needs degree >= 1 (a leading coefficient that is not 0 and at least one more)");
    }
    if num.is_empty() {
        return src.fail(
            "num",
            "is zero (or empty): the plant's output would be 0 whatever the input, nothing to control",
        );
    }
    if num.len() > den.len() {
        return src.fail(
            "num",
            format!(
                "degree {} above the denominator's {}: the transfer function is improper",
                num.len() - 1,
                den.len() - 1
            ),
        );
    }
    let n = den.len() - 1;
    if n > MAX_STATES - 1 {
        return src.fail("den", format!("degree {n}; at most {}", MAX_STATES - 1));
    }
    let lead = den[0];
    let den: Vec<f64> = den.iter().map(|x| x / lead).collect();
    let mut padded = vec![0.0; n + 1 - num.len()];
    padded.extend(num.iter().map(|x| x / lead));
    let mut a = vec![0.0; n * n];
    for j in 0..n {
        a[j] = -den[j + 1];
    }
    for i in 1..n {
        a[i * n + i - 1] = 1.0;
    }
    let mut b = vec![0.0; n];
    b[0] = 1.0;
    let c = (0..n).map(|j| padded[j + 1] - padded[0] * den[j + 1]).collect();
    Ok(Realised { n, m: 1, p: 1, a, b, c, d: vec![padded[0]] })
}

fn input_delay(check: &Check, delay: f64, period: f64) -> Result<usize, ConfigError> {
    let key = "plant.lti.input_delay";
    let delay = check.range(key, delay, 0.0, MAX_DELAY_PERIODS as f64 * period)?;
    let k = (delay / period).round();
    if (delay - k * period).abs() > 1e-9 * period.max(delay) {
        return check.fail(
            key,
            format!("{delay} s is not a whole number of control periods ({period} s)"),
        );
    }
    Ok(k as usize)
}

/// (Phi, Gamma) at `period`: the zero-order hold of a continuous model, (A, B) as they are for a
/// discrete one; the reason when the model is too fast to hold between samples. nalgebra's
/// exponential squares its argument ceil(log2 |M|) times, so |[A B] T| is bounded first: a huge
/// entry is an error, not an endless (or overflowing) exponential.
fn discretised(
    a: &[f64],
    b: &[f64],
    n: usize,
    m: usize,
    period: f64,
    discrete: bool,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    if discrete {
        return Ok((a.to_vec(), b.to_vec()));
    }
    let norm_t = norm_period(a.iter().chain(b), n + m, period);
    if norm_t > MAX_NORM_PERIOD {
        return Err(format!(
            "|[A B]| T is about {norm_t:.1e}: a model this fast (or stiff) against the control \
             period {period} s cannot be held between samples; scale it or sample faster"
        ));
    }
    let (phi, gamma) = zero_order_hold(a, b, n, m, period);
    if phi.iter().chain(&gamma).any(|v| !v.is_finite()) {
        return Err("exp(A T) overflows at the control period: the model is far too fast or \
                    unstable for it"
            .into());
    }
    Ok((phi, gamma))
}

/// The exact zero-order-hold discretisation at `t`: exp([[A, B], [0, 0]] t) = [[Phi, Gamma],
/// [0, I]] (Van Loan).
pub fn zero_order_hold(a: &[f64], b: &[f64], n: usize, m: usize, t: f64) -> (Vec<f64>, Vec<f64>) {
    let big = DMatrix::from_fn(n + m, n + m, |i, j| match (i < n, j < n) {
        (true, true) => a[i * n + j] * t,
        (true, false) => b[i * m + j - n] * t,
        _ => 0.0,
    })
    .exp();
    let phi = (0..n * n).map(|k| big[(k / n, k % n)]).collect();
    let gamma = (0..n * m).map(|k| big[(k / m, n + k % m)]).collect();
    (phi, gamma)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::PlantSim;
    use crate::reference::Reference;

    fn parse(toml: &str, period: f64) -> Result<LtiSpec, ConfigError> {
        let t: Table = evoloop_files::from_toml(toml).map_err(|p| p.reason).unwrap();
        let reference = Reference::Step {
            amplitude: 1.0,
            start: 0.0,
        };
        let cx = PlantContext {
            step: period,
            period,
            reference: &reference,
            duration: 1.0,
        };
        validate(Some(t), &Check::new("lti.toml".as_ref()), &cx)
    }

    /// A first-order lag x' = -x/tau + u/tau: Phi = e^{-T/tau}, Gamma = 1 - e^{-T/tau}.
    #[test]
    fn a_first_order_lag_discretises_to_its_closed_form() {
        let s = parse("a = [[-2.0]]\nb = [2.0]\nc = [1.0]", 0.1).unwrap();
        let e = (-0.2f64).exp();
        assert!((s.phi[0] - e).abs() < 1e-15, "{}", s.phi[0]);
        assert!((s.gamma[0] - (1.0 - e)).abs() < 1e-15, "{}", s.gamma[0]);
    }

    #[test]
    fn a_transfer_function_is_realised_as_scipys_tf2ss() {
        // (s + 3) / (2 s^2 + 4 s + 6): den normalised to s^2 + 2 s + 3.
        let s = parse("num = [1.0, 3.0]\nden = [2.0, 4.0, 6.0]", 0.01).unwrap();
        assert_eq!(s.a, [-2.0, -3.0, 1.0, 0.0]);
        assert_eq!(s.b, [1.0, 0.0]);
        assert_eq!(s.c, [0.5, 1.5]);
        assert_eq!(s.d, [0.0]);
        // Biproper: D takes the leading ratio.
        let s = parse("num = [1.0, 0.0]\nden = [1.0, 1.0]", 0.01).unwrap();
        assert_eq!((s.c[0], s.d[0]), (-1.0, 1.0));
    }

    /// Faddeev-LeVerrier and the Markov parameters give back a realised transfer function,
    /// and a physical-state model's: theta/V = 40 / (s^2 + 20 s).
    #[test]
    fn the_transfer_function_comes_back_from_the_state_space() {
        let s = parse("num = [1.0, 3.0]\nden = [2.0, 4.0, 6.0]", 0.01).unwrap();
        let (num, den) = s.transfer_function().unwrap();
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        assert!(close(&den, &[1.0, 2.0, 3.0]), "{den:?}");
        assert!(close(&num, &[0.0, 0.5, 1.5]), "{num:?}");
        let s = parse("a = [[0.0, 1.0], [0.0, -20.0]]\nb = [0.0, 40.0]\nc = [1.0, 0.0]", 0.001).unwrap();
        let (num, den) = s.transfer_function().unwrap();
        assert!(close(&den, &[1.0, 20.0, 0.0]) && close(&num, &[0.0, 0.0, 40.0]), "{num:?} {den:?}");
        assert_eq!(s.input_gain_at(0.0), Some(40.0));
    }

    /// A change takes over A and B at its time with the state carried over: before it the
    /// response is the first model's, after it the second's from the state it reached.
    #[test]
    fn a_change_switches_the_model_at_its_time_and_keeps_the_state() {
        let base = "a = [[0.0, 1.0], [0.0, -20.0]]\nb = [0.0, 40.0]\nc = [1.0, 0.0]\n";
        let changed = parse(
            &format!("{base}[[change]]\nat = 0.05\na = [[0.0, 1.0], [0.0, -5.0]]\nb = [0.0, 10.0]\n"),
            0.001,
        )
        .unwrap();
        let late = parse("a = [[0.0, 1.0], [0.0, -5.0]]\nb = [0.0, 10.0]\nc = [1.0, 0.0]", 0.001).unwrap();
        let first = parse(base, 0.001).unwrap();
        let mut sim = PlantSim::new(Box::new(changed.clone()), 0.001, 0.0, 1);
        let mut before = PlantSim::new(Box::new(first), 0.001, 0.0, 1);
        for _ in 0..50 {
            sim.advance(&[1.0], 0.001);
            before.advance(&[1.0], 0.001);
        }
        assert_eq!(sim.x, before.x);
        let mut after = PlantSim::new(Box::new(late), 0.001, 0.0, 1);
        after.x = sim.x.clone();
        for _ in 0..50 {
            sim.advance(&[1.0], 0.001);
            after.advance(&[1.0], 0.001);
        }
        assert_eq!(sim.x, after.x);
        assert_eq!(changed.input_gain_at(0.0), Some(40.0));
        assert_eq!(changed.input_gain_at(0.06), Some(10.0));
        // At 40 s the running sum of 1 ms periods falls 1e-11 s short of 40: the change still
        // takes effect with the period that starts there.
        let at40 = parse(
            &format!("{base}[[change]]\nat = 40.0\na = [[0.0, 1.0], [0.0, -5.0]]\nb = [0.0, 10.0]\n"),
            0.001,
        )
        .unwrap();
        let mut sim = PlantSim::new(Box::new(at40), 0.001, 0.0, 1);
        for _ in 0..40_000 {
            sim.advance(&[0.1], 0.001);
        }
        let mut after = PlantSim::new(
            Box::new(parse("a = [[0.0, 1.0], [0.0, -5.0]]\nb = [0.0, 10.0]\nc = [1.0, 0.0]", 0.001).unwrap()),
            0.001,
            0.0,
            1,
        );
        after.x = sim.x.clone();
        sim.advance(&[0.1], 0.001);
        after.advance(&[0.1], 0.001);
        assert_eq!(sim.x, after.x, "t = {}", sim.t);
        let e = parse(&format!("{base}[[change]]\nat = 1.0\nb = [1.0]\n"), 0.001).unwrap_err();
        assert_eq!(e.key, "plant.lti.change[0].b");
        let e = parse(&format!("{base}[[change]]\nat = 1.0\n"), 0.001).unwrap_err();
        assert_eq!(e.key, "plant.lti.change[0]");
    }

    #[test]
    fn wrong_sizes_name_the_key_and_both_sizes() {
        let e = parse("a = [[0.0, 1.0], [-1.0, -1.0]]\nb = [0.0, 1.0, 2.0]\nc = [1.0, 0.0]", 0.01)
            .unwrap_err();
        assert_eq!(e.key, "plant.lti.b");
        assert!(e.reason.contains("is 3 x 1, must be 2 x 1"), "{}", e.reason);
        let e = parse("num = [1.0, 2.0, 3.0]\nden = [1.0, 1.0]", 0.01).unwrap_err();
        assert_eq!(e.key, "plant.lti.num");
        assert!(e.reason.contains("improper"), "{}", e.reason);
        // An empty or zero numerator is a plant whose output never moves (issue 63, item 8).
        for num in ["[]", "[0.0, 0.0]"] {
            let e = parse(&format!("num = {num}\nden = [1.0, 1.0]"), 0.01).unwrap_err();
            assert_eq!(e.key, "plant.lti.num");
            assert!(e.reason.contains("nothing to control"), "{}", e.reason);
        }
        let e = parse("num = [1.0]\nden = [1.0, 1.0]\ninput_delay = 0.015", 0.01).unwrap_err();
        assert_eq!(e.key, "plant.lti.input_delay");
        let e = parse("num = [1.0]\nden = [1.0, 1.0]\ndt = 0.02", 0.01).unwrap_err();
        assert_eq!(e.key, "plant.lti.dt");
    }

    /// A delay of 3 periods: the first 3 periods' output is the free response, then the step's.
    #[test]
    fn an_input_delay_shifts_the_response_by_whole_periods() {
        let plain = parse("num = [1.0]\nden = [1.0, 1.0]", 0.1).unwrap();
        let late = parse("num = [1.0]\nden = [1.0, 1.0]\ninput_delay = 0.3", 0.1).unwrap();
        let run = |s: &LtiSpec| {
            let mut sim = PlantSim::new(Box::new(s.clone()), 0.1, 0.0, 1);
            let mut y = vec![];
            for _ in 0..10 {
                sim.advance(&[1.0], 0.1);
                let mut out = [0.0];
                sim.plant.output(&sim.x, &mut out);
                y.push(out[0]);
            }
            y
        };
        let (a, b) = (run(&plain), run(&late));
        assert_eq!(&b[..3], &[0.0; 3]);
        assert_eq!(&b[3..], &a[..7]);
    }

    /// Realtime's split periods integrate x' = A x + B u: within RK4's error of the exact step.
    #[test]
    fn a_split_period_integrates_close_to_the_exact_step() {
        let s = parse("a = [[0.0, 1.0], [-4.0, -0.4]]\nb = [0.0, 1.0]\nc = [1.0, 0.0]", 0.01).unwrap();
        let mut exact = PlantSim::new(Box::new(s.clone()), 0.001, 0.0, 1);
        let mut split = PlantSim::new(Box::new(s), 0.001, 0.0, 1);
        for _ in 0..100 {
            exact.advance(&[1.0], 0.01);
            split.advance(&[1.0], 0.0037);
            split.advance(&[1.0], 0.0063);
        }
        for i in 0..2 {
            assert!((exact.x[i] - split.x[i]).abs() < 1e-10, "{:?} {:?}", exact.x, split.x);
        }
    }

    #[test]
    fn the_command_is_clipped_and_a_feedthrough_acts_through_the_held_input() {
        let s = parse("num = [2.0, 0.0]\nden = [1.0, 1.0]\nu_min = [-1.0]\nu_max = [0.5]", 0.1).unwrap();
        let mut sim = PlantSim::new(Box::new(s), 0.1, 0.0, 1);
        let mut y = [0.0];
        sim.plant.output(&sim.x, &mut y);
        assert_eq!(y[0], 0.0, "nothing in force before the first command");
        sim.advance(&[3.0], 0.1);
        sim.plant.output(&sim.x, &mut y);
        // 2 s / (s + 1): y = 2 u e^{-t} for a step u; clipped to 0.5, at t = T.
        assert!((y[0] - (-0.1f64).exp()).abs() < 1e-14, "{}", y[0]);
    }
}
