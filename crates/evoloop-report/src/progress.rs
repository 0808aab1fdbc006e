//! Progress bars for the long commands (`tune`, `robust study`, `optim study`, `identify ...`,
//! `rkgnn study`, `bench ...`): elapsed time, position, ETA and the best cost so far, on stderr.
//! Hidden with `--quiet` or `--json`, and drawn only when stderr is a terminal (indicatif draws
//! nothing otherwise), so scripts and JSON on stdout stay clean.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar counting `unit`s (`len` 0: a count without a bar); hidden when `hidden`.
pub fn bar(len: u64, unit: &str, hidden: bool) -> ProgressBar {
    if hidden {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{prefix}}{{elapsed_precise}} [{{bar:30}}] {{pos}}/{{len}} {unit}, ETA {{eta}} {{msg}}"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar
}

/// A bar for an optimisation of `total` evaluations named `what`, whose callback reports
/// (evaluations so far, best cost): see `Optimisation::tell`.
pub struct Optimisation {
    bar: ProgressBar,
    cost: &'static str,
}

impl Optimisation {
    /// A bar of `total` evaluations prefixed `what`, the best cost shown under the name `cost`
    /// (e.g. "G"); hidden when `hidden`.
    pub fn new(what: &str, total: usize, cost: &'static str, hidden: bool) -> Self {
        let bar = bar(total as u64, "evaluations", hidden);
        bar.set_prefix(format!("{what}: "));
        Self { bar, cost }
    }

    /// Move the bar to `evaluations` done and show the best cost so far, `best`.
    pub fn tell(&self, evaluations: usize, best: f64) {
        self.bar.set_position(evaluations as u64);
        self.bar
            .set_message(format!("best {} {best:.4}", self.cost));
    }
}

impl Drop for Optimisation {
    /// The finished bar stays on the terminal, with its last best cost.
    fn drop(&mut self) {
        self.bar.abandon();
    }
}

/// Progress through a few long stages (a measurement each, run by a child process): the stage's
/// name and the elapsed time, ticking on its own.
pub struct Stages {
    bar: ProgressBar,
    started: std::cell::Cell<bool>,
}

/// `n` stages counted in `unit`; hidden when `hidden`.
pub fn stages(n: u64, unit: &str, hidden: bool) -> Stages {
    let bar = bar(n, unit, hidden);
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    Stages {
        bar,
        started: std::cell::Cell::new(false),
    }
}

impl Stages {
    /// The previous stage is done and `name` starts.
    pub fn inc_stage(&self, name: &str) {
        if self.started.replace(true) {
            self.bar.inc(1);
        }
        self.bar.set_message(name.to_string());
    }

    /// What the current stage is doing now, without counting a new one.
    pub fn set_message(&self, what: &str) {
        self.bar.set_message(what.to_string());
    }
}

impl Drop for Stages {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
