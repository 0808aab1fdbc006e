//! Scalar recursive least squares with exponential forgetting, y = theta x + e: the estimator
//! behind every model adaptation of the indirect scheme.

#[derive(Debug, Clone)]
pub struct Rls {
    pub theta: f64,
    p: f64,
    lambda: f64,
    /// Exponentially weighted variance of the prediction error.
    sigma2: f64,
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

#[cfg(test)]
mod tests {
    use super::Rls;

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
}
