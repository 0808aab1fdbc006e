//! Scalar recursive least squares with exponential forgetting, y = theta x + e: the estimator
//! behind every model adaptation of the indirect scheme.

/// Scalar recursive least squares with exponential forgetting: the estimate of theta in
/// y = theta x + e, forgetting old data by `lambda` per update.
#[derive(Debug, Clone)]
pub struct Rls {
    /// The current estimate of theta.
    pub theta: f64,
    p: f64,
    lambda: f64,
    /// Exponentially weighted variance of the prediction error.
    sigma2: f64,
    /// Observations fed so far.
    pub updates: u64,
}

impl Rls {
    /// Start at `theta0` with a vague prior; forgetting factor `lambda` per update.
    pub fn new(theta0: f64, lambda: f64) -> Self {
        Self {
            theta: theta0,
            p: 1e3,
            lambda,
            sigma2: 1.0,
            updates: 0,
        }
    }

    /// One observation y = theta x + e: moves theta by the gain times the prediction error and
    /// forgets by `lambda`.
    pub fn update(&mut self, y: f64, x: f64) {
        let e = y - self.theta * x;
        let k = self.p * x / (self.lambda + x * self.p * x);
        self.theta += k * e;
        self.p = (self.p - k * x * self.p) / self.lambda;
        self.sigma2 = self.lambda * self.sigma2 + (1.0 - self.lambda) * e * e;
        self.updates += 1;
    }

    /// Standard deviation of theta.
    pub fn std(&self) -> f64 {
        (self.p * self.sigma2).max(0.0).sqrt()
    }
}

/// Scalar least squares that forgets old data only as fast as new data replaces them: the
/// information sum S = sum(lambda-weighted x^2) is held near the amount that gives a relative
/// standard deviation `rel_std` at the given noise level (S* = sigma^2 / (rel_std theta)^2), by
/// discounting with lambda = exp(-x^2 / S*) at each update. Without excitation (x ~ 0) nothing is
/// forgotten, so the gain cannot wind up between transients (exponential forgetting's failure on
/// a plant that rests between set-point changes); with rich excitation old data go as soon as
/// new data carry the same information, so a drifting parameter is followed.
///
/// Information also fades with a long time constant (`memory` updates) whatever the excitation:
/// otherwise a parameter that drifts while the loop is barely excited (a sluggish controller in
/// service) would stay on the value the last strong transient left. The gain's growth at rest is
/// then bounded by e^(rest / memory) instead of the lambda^-n of exponential forgetting.
///
/// The noise variance sigma^2 of y is the caller's, measured independently of the fit: taken
/// from the prediction errors it would include the parameter error itself and slow the
/// forgetting exactly when the parameter changes.
#[derive(Debug, Clone)]
pub struct InformationRls {
    /// The current estimate of theta.
    pub theta: f64,
    /// Discounted information sum, 1 / P.
    info: f64,
    rel_std: f64,
    /// Discount per update from the time constant alone.
    fade: f64,
    sigma2: f64,
    /// Observations fed so far.
    pub updates: u64,
}

impl InformationRls {
    /// Start at `theta0` with the information of one unit regressor; `rel_std` is the target
    /// relative standard deviation, `memory` the time constant of fading in updates.
    pub fn new(theta0: f64, rel_std: f64, memory: f64) -> Self {
        Self {
            theta: theta0,
            info: 1.0,
            rel_std,
            fade: (-1.0 / memory.max(1.0)).exp(),
            sigma2: 0.0,
            updates: 0,
        }
    }

    /// One observation y = theta x + e with var(e) = `noise_var`.
    pub fn update(&mut self, y: f64, x: f64, noise_var: f64) {
        self.sigma2 = noise_var.max(0.0);
        let e = y - self.theta * x;
        let scale = (self.rel_std * self.theta).abs().max(f64::MIN_POSITIVE);
        let wanted = (self.sigma2 / (scale * scale)).max(f64::MIN_POSITIVE);
        self.info = self.info * self.fade * (-x * x / wanted).exp() + x * x;
        self.theta += x * e / self.info;
        self.updates += 1;
    }

    /// Standard deviation of theta: sigma / sqrt(S).
    pub fn std(&self) -> f64 {
        (self.sigma2 / self.info).sqrt()
    }
}
