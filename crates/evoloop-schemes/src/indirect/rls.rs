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

#[cfg(test)]
mod tests {
    use super::{InformationRls, Rls};

    #[test]
    fn converges_to_the_true_slope_and_follows_a_change() {
        let mut r = Rls::new(0.0, 0.99);
        let x = |k: usize| 1.0 + (k as f64 * 0.37).sin();
        for k in 0..1000 {
            r.update(2.0 * x(k), x(k));
        }
        assert!((r.theta - 2.0).abs() < 1e-9, "{}", r.theta);
        // After a change the old data fade as lambda^n: 0.99^1000 ~ 4e-5.
        for k in 1000..2000 {
            r.update(3.0 * x(k), x(k));
        }
        assert!((r.theta - 3.0).abs() < 1e-3, "{}", r.theta);
        assert_eq!(r.updates, 2000);
    }

    /// Noisy data with pauses in the excitation: the information forgetting neither winds up
    /// in the pauses nor stays on the old value after a change, and its reported deviation
    /// covers the error.
    #[test]
    fn information_forgetting_follows_a_change_across_pauses() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut r = InformationRls::new(1.0, 0.005, 1e5);
        // Uniform noise of standard deviation 0.1.
        let mut noise = || 0.1 * (rng.gen::<f64>() - 0.5) * 12f64.sqrt();
        // Excitation for 500 samples, rest (x = 1e-4) for 5000, three times; the slope 2 -> 3.
        for (slope, phase) in [(2.0, 0), (2.0, 1), (3.0, 2), (3.0, 3)] {
            for k in 0..5500 {
                let x = if k < 500 {
                    1.0 + (k as f64 * 0.37).sin()
                } else {
                    1e-4
                };
                r.update(slope * x + noise(), x, 0.01);
            }
            let err = (r.theta - slope).abs();
            assert!(
                err <= 3.0 * r.std(),
                "phase {phase}: theta {} std {}",
                r.theta,
                r.std()
            );
            assert!(r.std() / slope < 0.01, "phase {phase}: std {}", r.std());
        }
    }
}
