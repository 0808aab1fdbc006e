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
    // A duration the loop can resolve: at least `periods` control periods.
    let resolvable = |key: &str, x: f64, periods: f64, what: &str| {
        check.positive(key, x)?;
        if x < periods * control_period * (1.0 - 1e-9) {
            return check.fail(
                key,
                format!(
                    "{x} s is shorter than {periods} control period(s) ({} s): {what}",
                    periods * control_period
                ),
            );
        }
        Ok(x)
    };
    // A scalar value, bounded so that errors and their integrals (IAE, ISE) stay finite.
    let value = |key: &str, x: f64| check.range(key, x, -MAX_VALUE, MAX_VALUE);
    let need = |key: &str, v: Option<f64>| -> Result<f64, ConfigError> {
        match v {
            Some(x) => value(&format!("reference.{key}"), x),
            None => check.fail(
                &format!("reference.{key}"),
                "missing (required for this reference kind)",
            ),
        }
    };
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
    for (k, p) in present {
        if p && !allowed.contains(&k) {
            return check.fail(
                &format!("reference.{k}"),
                format!(
                    "not used by a `{kind_name}` reference (it takes {}); remove it",
                    allowed.join(", ")
                ),
            );
        }
    }
    let joints = |key: &str, v: &[f64], n: usize| -> Result<(), ConfigError> {
        if n == 0 || n > crate::MAX_JOINTS {
            return check.fail(key, format!("1..={} joints, got {n}", crate::MAX_JOINTS));
        }
        check.finite_values(key, v, n, " (one per joint)")
    };
    match r.kind {
        ReferenceKind::Excitation => {
            let Some(file) = r.file else {
                return check.fail(
                    "reference.file",
                    "an excitation reference needs `file` (from `evoloop identify excitation --out`)",
                );
            };
            let path = check.resolve(&file);
            let series = excitation_file(&path)
                .or_else(|e| check.fail("reference.file", format!("{}: {e}", path.display())))?;
            Ok(series.to_reference())
        }
        ReferenceKind::Quintic => {
            let (Some(times), Some(waypoints)) = (r.times, r.waypoints) else {
                return check.fail("reference.waypoints", "a quintic trajectory needs `times` and `waypoints` (one array of joint values per time)");
            };
            if times.len() < 2 || times.len() != waypoints.len() {
                return check.fail(
                    "reference.waypoints",
                    format!(
                        "needs at least 2 waypoints, as many as `times` ({}), got {}",
                        times.len(),
                        waypoints.len()
                    ),
                );
            }
            let n = waypoints[0].len();
            for (k, w) in waypoints.iter().enumerate() {
                joints(&format!("reference.waypoints[{k}]"), w, n)?;
            }
            for i in 0..times.len() {
                check.range(&format!("reference.times[{i}]"), times[i], 0.0, 1e9)?;
                if i > 0 && times[i] <= times[i - 1] {
                    return check.fail(
                        &format!("reference.times[{i}]"),
                        "times must be strictly increasing",
                    );
                }
            }
            Ok(Reference::Quintic { times, waypoints })
        }
        ReferenceKind::Sines => {
            let (Some(offsets), Some(amplitudes), Some(frequencies)) =
                (r.offsets, r.amplitudes, r.frequencies)
            else {
                return check.fail("reference.amplitudes", "a sum of sinusoids needs `offsets` (per joint), `amplitudes` (per joint, per frequency) and `frequencies` (Hz)");
            };
            let n = offsets.len();
            joints("reference.offsets", &offsets, n)?;
            if frequencies.is_empty() {
                return check.fail("reference.frequencies", "needs at least one frequency");
            }
            // Up to the loop's Nyquist rate, 1 / (2 period).
            let nyquist = 0.5 / control_period;
            for (h, f) in frequencies.iter().enumerate() {
                check.range(&format!("reference.frequencies[{h}]"), *f, 0.0, nyquist)?;
            }
            let nh = frequencies.len();
            let phases = r.phases.unwrap_or_else(|| vec![vec![0.0; nh]; n]);
            for (key, m) in [("amplitudes", &amplitudes), ("phases", &phases)] {
                if m.len() != n {
                    return check.fail(
                        &format!("reference.{key}"),
                        format!("needs {n} rows (one per joint), got {}", m.len()),
                    );
                }
                for (j, row) in m.iter().enumerate() {
                    check.finite_values(
                        &format!("reference.{key}[{j}]"),
                        row,
                        nh,
                        " (one per frequency)",
                    )?;
                }
            }
            Ok(Reference::Sines {
                offsets,
                amplitudes,
                frequencies,
                phases,
            })
        }
        ReferenceKind::Samples => {
            let (Some(values), Some(period)) = (r.values, r.period) else {
                return check.fail(
                    "reference.values",
                    "a sampled sequence needs `values` and `period` (s between them); it repeats",
                );
            };
            if values.is_empty() || values.len() > 1_000_000 {
                return check.fail("reference.values", "needs 1..=1000000 values");
            }
            for (i, v) in values.iter().enumerate() {
                value(&format!("reference.values[{i}]"), *v)?;
            }
            resolvable(
                "reference.period",
                period,
                1.0,
                "the loop would skip samples",
            )?;
            Ok(Reference::Samples { values, period })
        }
        ReferenceKind::Step => Ok(Reference::Step {
            amplitude: need("amplitude", r.amplitude)?,
            start: check.range("reference.start", r.start.unwrap_or(0.0), 0.0, 1e9)?,
        }),
        ReferenceKind::Square => {
            let period = need("period", r.period)?;
            resolvable(
                "reference.period",
                period,
                2.0,
                "the loop could not follow the wave",
            )?;
            Ok(Reference::Square {
                amplitude: need("amplitude", r.amplitude)?,
                period,
                offset: value("reference.offset", r.offset.unwrap_or(0.0))?,
                start: check.range("reference.start", r.start.unwrap_or(0.0), 0.0, 1e9)?,
            })
        }
        ReferenceKind::Steps => {
            let (Some(times), Some(values)) = (r.times, r.values) else {
                return check.fail(
                    "reference.times",
                    "a step sequence needs `times` and `values` arrays",
                );
            };
            if times.is_empty() || times.len() != values.len() {
                return check.fail(
                    "reference.values",
                    format!(
                        "needs as many entries as `times` ({}), got {}",
                        times.len(),
                        values.len()
                    ),
                );
            }
            for i in 0..times.len() {
                check.finite(&format!("reference.times[{i}]"), times[i])?;
                value(&format!("reference.values[{i}]"), values[i])?;
                if i > 0 && times[i] <= times[i - 1] {
                    return check.fail(
                        &format!("reference.times[{i}]"),
                        "times must be strictly increasing",
                    );
                }
            }
            Ok(Reference::Steps { times, values })
        }
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
    if n == 0 || n > crate::MAX_JOINTS {
        return Err(format!(
            "`series`: 1..={} joints, got {n}",
            crate::MAX_JOINTS
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
