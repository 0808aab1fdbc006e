//! `evoloop check FILE`: validate a scenario without starting anything.

use std::path::Path;
use std::process::ExitCode;

/// `evoloop check FILE`: load and validate the scenario `file` without starting a process, print
/// its warnings and a one-line summary of what it resolves to. Exit code 2 if it does not load.
pub fn check(file: &Path) -> ExitCode {
    match evoloop_run::node::start::load(file, &Default::default()) {
        Ok(s) => {
            for w in &s.warnings {
                err!("warning: {w}");
            }
            out!(
                "{}: ok: scenario `{}`, plant {:?}, controller {:?}, reference {}, {} mode, period {} s, {}, optimiser {:?} with {} scheduled set(s), output {}",
                file.display(),
                s.name,
                s.plant.kind(),
                s.controller.kind(),
                s.reference.describe(),
                s.timing.mode,
                s.timing.period,
                if s.timing.until_stopped() {
                    s.timing.span()
                } else {
                    format!("{} ({} cycles)", s.timing.span(), s.cycles())
                },
                s.optimiser.mode,
                s.optimiser.schedule.len(),
                s.output.dir.display()
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            err!("error: {e}");
            ExitCode::from(2)
        }
    }
}
