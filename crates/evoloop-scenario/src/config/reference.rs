//! The `[reference]` table: the set-point trajectory every plant follows.

use crate::check::{Check, ConfigError};
use crate::reference::{Reference, MAX_VALUE};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawReference {
    pub kind: ReferenceKind,
    pub amplitude: Option<f64>,
    pub start: Option<f64>,
    pub period: Option<f64>,
    pub offset: Option<f64>,
    pub times: Option<Vec<f64>>,
    pub values: Option<Vec<f64>>,
    pub waypoints: Option<Vec<Vec<f64>>>,
    pub offsets: Option<Vec<f64>>,
    pub amplitudes: Option<Vec<Vec<f64>>>,
    pub frequencies: Option<Vec<f64>>,
    pub phases: Option<Vec<Vec<f64>>>,
    /// An excitation trajectory file (`evoloop identify excitation --out`), relative to the
    /// scenario file.
    pub file: Option<std::path::PathBuf>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReferenceKind {
    Step,
    Square,
    Steps,
    Quintic,
    Sines,
    Excitation,
    Samples,
}

/// The reference of a loop run every `control_period` seconds: its times are checked against it
/// (a square wave of period 1e-12 s passed before, as did sines above the loop's Nyquist rate).
pub fn validate(
    r: RawReference,
    check: &Check,
    control_period: f64,
) -> Result<Reference, ConfigError> {
    let c = RefCheck {
        check,
        control_period,
    };
    c.only_used_keys(&r)?;
    match r.kind {
        ReferenceKind::Excitation => c.excitation(r),
        ReferenceKind::Quintic => c.quintic(r),
        ReferenceKind::Sines => c.sines(r),
        ReferenceKind::Samples => c.samples(r),
        ReferenceKind::Step => c.step(r),
        ReferenceKind::Square => c.square(r),
        ReferenceKind::Steps => c.steps(r),
    }
}

/// The checks of one reference table, each kind's in its own method.
struct RefCheck<'a> {
    check: &'a Check,
    control_period: f64,
}

impl RefCheck<'_> {
    /// A key the kind does not use is refused (it would be silently ignored).
    fn only_used_keys(&self, r: &RawReference) -> Result<(), ConfigError> {
        let present = [
            ("amplitude", r.amplitude.is_some()),
            ("start", r.start.is_some()),
            ("period", r.period.is_some()),
            ("offset", r.offset.is_some()),
            ("times", r.times.is_some()),
            ("values", r.values.is_some()),
            ("waypoints", r.waypoints.is_some()),
            ("offsets", r.offsets.is_some()),
            ("amplitudes", r.amplitudes.is_some()),
            ("frequencies", r.frequencies.is_some()),
            ("phases", r.phases.is_some()),
            ("file", r.file.is_some()),
        ];
        let (kind_name, allowed): (&str, &[&str]) = match r.kind {
            ReferenceKind::Step => ("step", &["amplitude", "start"]),
            ReferenceKind::Square => ("square", &["amplitude", "period", "offset", "start"]),
            ReferenceKind::Steps => ("steps", &["times", "values"]),
            ReferenceKind::Quintic => ("quintic", &["times", "waypoints"]),
            ReferenceKind::Sines => ("sines", &["offsets", "amplitudes", "frequencies", "phases"]),
            ReferenceKind::Excitation => ("excitation", &["file"]),
            ReferenceKind::Samples => ("samples", &["values", "period"]),
        };
        match present.iter().find(|(k, p)| *p && !allowed.contains(k)) {
            Some((k, _)) => self.check.fail(
                &format!("reference.{k}"),
                format!(
                    "not used by a `{kind_name}` reference (it takes {}); remove it",
                    allowed.join(", ")
                ),
            ),
            None => Ok(()),
        }
    }

    /// A duration the loop can resolve: at least `periods` control periods.
    fn resolvable(&self, key: &str, x: f64, periods: f64, what: &str) -> Result<f64, ConfigError> {
        self.check.positive(key, x)?;
        let shortest = periods * self.control_period;
        if x < shortest * (1.0 - 1e-9) {
            return self.check.fail(
                key,
                format!("{x} s is shorter than {periods} control period(s) ({shortest} s): {what}"),
            );
        }
        Ok(x)
    }

    /// A scalar value, bounded so that errors and their integrals (IAE, ISE) stay finite.
    fn value(&self, key: &str, x: f64) -> Result<f64, ConfigError> {
        self.check.range(key, x, -MAX_VALUE, MAX_VALUE)
    }

    /// A value the kind requires.
    fn need(&self, key: &str, v: Option<f64>) -> Result<f64, ConfigError> {
        let key = format!("reference.{key}");
        match v {
            Some(x) => self.value(&key, x),
            None => self
                .check
                .fail(&key, "missing (required for this reference kind)"),
        }
    }

    fn start(&self, start: Option<f64>) -> Result<f64, ConfigError> {
        self.check
            .range("reference.start", start.unwrap_or(0.0), 0.0, 1e9)
    }

    /// `n` finite joint values.
    fn joints(&self, key: &str, v: &[f64], n: usize) -> Result<(), ConfigError> {
        if n == 0 || n > crate::msg::MAX_JOINTS {
            let most = crate::msg::MAX_JOINTS;
            return self.check.fail(key, format!("1..={most} joints, got {n}"));
        }
        self.check.finite_values(key, v, n, " (one per joint)")
    }

    /// Times strictly increasing, each checked by `each`.
    fn increasing(
        &self,
        times: &[f64],
        each: impl Fn(usize, &str, f64) -> Result<f64, ConfigError>,
    ) -> Result<(), ConfigError> {
        for i in 0..times.len() {
            let key = format!("reference.times[{i}]");
            each(i, &key, times[i])?;
            if i > 0 && times[i] <= times[i - 1] {
                return self.check.fail(&key, "times must be strictly increasing");
            }
        }
        Ok(())
    }

    fn excitation(&self, r: RawReference) -> Result<Reference, ConfigError> {
        let Some(file) = r.file else {
            return self.check.fail(
                "reference.file",
                "an excitation reference needs `file` (from `evoloop identify excitation --out`)",
            );
        };
        let path = self.check.resolve(&file);
        let series = excitation_file(&path).or_else(|e| {
            let at = path.display();
            self.check.fail("reference.file", format!("{at}: {e}"))
        })?;
        Ok(series.to_reference())
    }

    fn quintic(&self, r: RawReference) -> Result<Reference, ConfigError> {
        let (Some(times), Some(waypoints)) = (r.times, r.waypoints) else {
            return self.check.fail("reference.waypoints", "a quintic trajectory needs `times` and `waypoints` (one array of joint values per time)");
        };
        if times.len() < 2 || times.len() != waypoints.len() {
            let (t, w) = (times.len(), waypoints.len());
            return self.check.fail(
                "reference.waypoints",
                format!("needs at least 2 waypoints, as many as `times` ({t}), got {w}"),
            );
        }
        let n = waypoints[0].len();
        for (k, w) in waypoints.iter().enumerate() {
            self.joints(&format!("reference.waypoints[{k}]"), w, n)?;
        }
        self.increasing(&times, |_, key, t| self.check.range(key, t, 0.0, 1e9))?;
        Ok(Reference::Quintic { times, waypoints })
    }

    fn sines(&self, r: RawReference) -> Result<Reference, ConfigError> {
        let (Some(offsets), Some(amplitudes), Some(frequencies)) =
            (r.offsets, r.amplitudes, r.frequencies)
        else {
            return self.check.fail("reference.amplitudes", "a sum of sinusoids needs `offsets` (per joint), `amplitudes` (per joint, per frequency) and `frequencies` (Hz)");
        };
        let n = offsets.len();
        self.joints("reference.offsets", &offsets, n)?;
        if frequencies.is_empty() {
            return self
                .check
                .fail("reference.frequencies", "needs at least one frequency");
        }
        // Up to the loop's Nyquist rate, 1 / (2 period).
        let nyquist = 0.5 / self.control_period;
        for (h, f) in frequencies.iter().enumerate() {
            let key = format!("reference.frequencies[{h}]");
            self.check.range(&key, *f, 0.0, nyquist)?;
        }
        let nh = frequencies.len();
        let phases = r.phases.unwrap_or_else(|| vec![vec![0.0; nh]; n]);
        for (key, m) in [("amplitudes", &amplitudes), ("phases", &phases)] {
            if m.len() != n {
                let got = m.len();
                return self.check.fail(
                    &format!("reference.{key}"),
                    format!("needs {n} rows (one per joint), got {got}"),
                );
            }
            for (j, row) in m.iter().enumerate() {
                let key = format!("reference.{key}[{j}]");
                self.check
                    .finite_values(&key, row, nh, " (one per frequency)")?;
            }
        }
        Ok(Reference::Sines {
            offsets,
            amplitudes,
            frequencies,
            phases,
        })
    }

    fn samples(&self, r: RawReference) -> Result<Reference, ConfigError> {
        let (Some(values), Some(period)) = (r.values, r.period) else {
            return self.check.fail(
                "reference.values",
                "a sampled sequence needs `values` and `period` (s between them); it repeats",
            );
        };
        if values.is_empty() || values.len() > 1_000_000 {
            return self
                .check
                .fail("reference.values", "needs 1..=1000000 values");
        }
        for (i, v) in values.iter().enumerate() {
            self.value(&format!("reference.values[{i}]"), *v)?;
        }
        let skips = "the loop would skip samples";
        self.resolvable("reference.period", period, 1.0, skips)?;
        Ok(Reference::Samples { values, period })
    }

    fn step(&self, r: RawReference) -> Result<Reference, ConfigError> {
        Ok(Reference::Step {
            amplitude: self.need("amplitude", r.amplitude)?,
            start: self.start(r.start)?,
        })
    }

    fn square(&self, r: RawReference) -> Result<Reference, ConfigError> {
        let period = self.need("period", r.period)?;
        let cannot = "the loop could not follow the wave";
        self.resolvable("reference.period", period, 2.0, cannot)?;
        Ok(Reference::Square {
            amplitude: self.need("amplitude", r.amplitude)?,
            period,
            offset: self.value("reference.offset", r.offset.unwrap_or(0.0))?,
            start: self.start(r.start)?,
        })
    }

    fn steps(&self, r: RawReference) -> Result<Reference, ConfigError> {
        let (Some(times), Some(values)) = (r.times, r.values) else {
            return self.check.fail(
                "reference.times",
                "a step sequence needs `times` and `values` arrays",
            );
        };
        if times.is_empty() || times.len() != values.len() {
            let (t, v) = (times.len(), values.len());
            return self.check.fail(
                "reference.values",
                format!("needs as many entries as `times` ({t}), got {v}"),
            );
        }
        // Each time's value is checked with it, in order.
        self.increasing(&times, |i, key, t| {
            self.check.finite(key, t)?;
            self.value(&format!("reference.values[{i}]"), values[i])
        })?;
        Ok(Reference::Steps { times, values })
    }
}

/// The joint-space Fourier series of an excitation file (its `series`), checked.
fn excitation_file(
    path: &std::path::Path,
) -> Result<crate::reference::series::FourierSeries, String> {
    let text = crate::files::read_text(path).map_err(|e| format!("cannot read: {e}"))?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let s: crate::reference::series::FourierSeries = serde_json::from_value(v["series"].clone())
        .map_err(|e| format!("`series`: {e} (not an `evoloop identify excitation` file?)"))?;
    let n = s.offsets.len();
    let h = s.harmonics();
    if n == 0 || n > crate::msg::MAX_JOINTS {
        return Err(format!(
            "`series`: 1..={} joints, got {n}",
            crate::msg::MAX_JOINTS
        ));
    }
    if h == 0 || s.a.len() != n || s.b.len() != n || s.a.iter().chain(&s.b).any(|r| r.len() != h) {
        return Err("`series`: `a` and `b` need one row per joint, one entry per harmonic".into());
    }
    if !(s.period.is_finite() && s.period > 0.0)
        || s.offsets
            .iter()
            .chain(s.a.iter().flatten())
            .chain(s.b.iter().flatten())
            .any(|x| !x.is_finite())
    {
        return Err("`series`: period must be > 0 and every value finite".into());
    }
    Ok(s)
}
