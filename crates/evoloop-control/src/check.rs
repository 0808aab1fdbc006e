//! Checking configuration values: the error that names file, key and reason, and the checks every
//! configurable kind (plants, controllers, the scenario's shared tables) builds its validation
//! from. It sits below the kinds so each can own its `[plant.<kind>]` or `[controller.<kind>]`
//! table next to its code (see `kinds!`) without reaching up into the scenario loader.

use crate::dynamics::Model;
use std::cell::RefCell;
use std::fmt;
use std::path::{Path, PathBuf};

/// A configuration error: file, key and reason.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    /// The file the error is in: the scenario file, or a file it names (an LTI model file).
    pub file: PathBuf,
    /// Dotted key path (`plant.two_mass.spring`); empty for file-level errors.
    pub key: String,
    /// What is wrong, with the value given where it helps (`must be finite (got NaN)`).
    pub reason: String,
    /// 1-based line, when known.
    pub line: Option<usize>,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        if !self.key.is_empty() {
            write!(f, ": key `{}`", self.key)?;
        }
        write!(f, ": {}", self.reason)
    }
}

impl std::error::Error for ConfigError {}

/// Per-parameter inclusive bounds from the config, which every received set must respect.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ParamBounds {
    /// The lowest value of each parameter, in the law's parameter order.
    pub lower: Vec<f64>,
    /// The highest value of each parameter, in the law's parameter order.
    pub upper: Vec<f64>,
}

/// A tunable parameter vector as configured: its initial values and their bounds.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Tunable {
    /// The initial values: the set in service before the optimiser sends one.
    pub gains: Vec<f64>,
    /// The inclusive bounds of each value (`lower`, `upper` beside `gains` when serialised).
    #[serde(flatten)]
    pub bounds: ParamBounds,
}

/// The checks, bound to the file being validated. Each returns the value it accepted or the
/// error naming `key`.
pub struct Check {
    /// The file being validated: errors name it, relative paths resolve from its directory.
    pub file: PathBuf,
    /// Robot-file warnings met while validating (interior mutability: the checks take `&self`).
    warnings: RefCell<Vec<String>>,
}

impl Check {
    /// The checks for `file`, with no warnings collected yet.
    pub fn new(file: &Path) -> Self {
        Self {
            file: file.to_path_buf(),
            warnings: Default::default(),
        }
    }

    /// The warnings collected so far (robot files that load but are physically dubious).
    pub fn take_warnings(&self) -> Vec<String> {
        self.warnings.take()
    }

    /// Always `Err`: the error naming `key` in this file with `reason`, typed to fit the caller.
    pub fn fail<T>(&self, key: &str, reason: impl Into<String>) -> Result<T, ConfigError> {
        Err(ConfigError {
            file: self.file.clone(),
            key: key.to_string(),
            reason: reason.into(),
            line: None,
        })
    }

    /// `v` if it is finite and > 0, else an error naming `key`.
    pub fn positive(&self, key: &str, v: f64) -> Result<f64, ConfigError> {
        if !v.is_finite() || v <= 0.0 {
            return self.fail(key, format!("must be a finite number > 0 (got {v})"));
        }
        Ok(v)
    }

    /// `v` if it is finite (neither NaN nor infinite), else an error naming `key`.
    pub fn finite(&self, key: &str, v: f64) -> Result<f64, ConfigError> {
        if !v.is_finite() {
            return self.fail(key, format!("must be finite (got {v})"));
        }
        Ok(v)
    }

    /// `v` if it lies within `lo..=hi` (NaN does not), else an error naming `key`.
    pub fn range(&self, key: &str, v: f64, lo: f64, hi: f64) -> Result<f64, ConfigError> {
        if !(v >= lo && v <= hi) {
            return self.fail(key, format!("must be within [{lo}, {hi}] (got {v})"));
        }
        Ok(v)
    }

    /// A whole number within `lo..=hi` (a count, a priority, a niceness).
    pub fn count<T>(&self, key: &str, v: T, lo: T, hi: T) -> Result<T, ConfigError>
    where
        T: PartialOrd + std::fmt::Display + Copy,
    {
        if !(lo..=hi).contains(&v) {
            return self.fail(key, format!("must be {lo}..={hi} (got {v})"));
        }
        Ok(v)
    }

    /// `v` has exactly `n` finite values (`what` says what they are per, e.g. " (one per joint)").
    pub fn finite_values(
        &self,
        key: &str,
        v: &[f64],
        n: usize,
        what: &str,
    ) -> Result<(), ConfigError> {
        if v.len() != n {
            return self.fail(key, format!("needs {n} values{what}, got {}", v.len()));
        }
        for (i, x) in v.iter().enumerate() {
            self.finite(&format!("{key}[{i}]"), *x)?;
        }
        Ok(())
    }

    /// Refuse a key that is present but means nothing here.
    pub fn unused(&self, key: &str, present: bool, why: &str) -> Result<(), ConfigError> {
        if present {
            return self.fail(key, format!("not used {why}; remove it"));
        }
        Ok(())
    }

    /// A (time, value) schedule from two arrays: same length, 1..=`max` points, times
    /// increasing, values positive.
    pub fn schedule(
        &self,
        key_t: &str,
        key_v: &str,
        times: Option<Vec<f64>>,
        values: Option<Vec<f64>>,
        max: usize,
    ) -> Result<Vec<(f64, f64)>, ConfigError> {
        let (times, values) = match (times, values) {
            (None, None) => return Ok(Vec::new()),
            (Some(t), Some(v)) => (t, v),
            (Some(_), None) => return self.fail(key_v, "missing (required with its times)"),
            (None, Some(_)) => return self.fail(key_t, "missing (required with its values)"),
        };
        if times.is_empty() || times.len() > max || times.len() != values.len() {
            return self.fail(
                key_v,
                format!(
                    "needs 1..={max} entries, as many as the times ({} times, {} values)",
                    times.len(),
                    values.len()
                ),
            );
        }
        for i in 0..times.len() {
            self.range(&format!("{key_t}[{i}]"), times[i], 0.0, 1e9)?;
            self.range(&format!("{key_v}[{i}]"), values[i], 1e-6, 1e6)?;
            if i > 0 && times[i] <= times[i - 1] {
                return self.fail(
                    &format!("{key_t}[{i}]"),
                    "times must be strictly increasing",
                );
            }
        }
        Ok(times.into_iter().zip(values).collect())
    }

    /// A tunable gain vector under `key` (`<key>.gains`, `<key>.lower`, `<key>.upper`) with its
    /// bounds: finite, as many bounds as gains, lower <= gain <= upper. Missing bounds default to
    /// +-`default_bound`.
    pub fn tunable(
        &self,
        key: &str,
        gains: Vec<f64>,
        lower: Option<Vec<f64>>,
        upper: Option<Vec<f64>>,
        default_bound: f64,
    ) -> Result<Tunable, ConfigError> {
        let n = gains.len();
        for (i, g) in gains.iter().enumerate() {
            self.finite(&format!("{key}.gains[{i}]"), *g)?;
        }
        let lower = lower.unwrap_or_else(|| vec![-default_bound; n]);
        let upper = upper.unwrap_or_else(|| vec![default_bound; n]);
        for (k, b) in [("lower", &lower), ("upper", &upper)] {
            self.finite_values(&format!("{key}.{k}"), b, n, "")?;
        }
        for i in 0..n {
            if lower[i] > upper[i] {
                return self.fail(
                    &format!("{key}.lower[{i}]"),
                    format!("lower bound {} is above upper bound {}", lower[i], upper[i]),
                );
            }
            if gains[i] < lower[i] || gains[i] > upper[i] {
                return self.fail(
                    &format!("{key}.gains[{i}]"),
                    format!(
                        "{} is outside its bounds [{}, {}]",
                        gains[i], lower[i], upper[i]
                    ),
                );
            }
        }
        Ok(Tunable {
            gains,
            bounds: ParamBounds { lower, upper },
        })
    }

    /// A path from the config, relative to the scenario file's directory.
    pub fn resolve(&self, rel: &Path) -> PathBuf {
        if rel.is_absolute() {
            rel.to_path_buf()
        } else {
            self.file.parent().unwrap_or(Path::new(".")).join(rel)
        }
    }

    /// A robot file named by `key`, loaded and checked; its errors keep their own file and item,
    /// its warnings are collected for `evoloop check` and the launcher to print.
    pub fn robot(&self, key: &str, rel: &Path) -> Result<(PathBuf, Model), ConfigError> {
        let path = self.resolve(rel);
        match crate::dynamics::load_with(&path, &Default::default()) {
            Ok(l) => {
                let mut w = self.warnings.borrow_mut();
                for x in l.warnings {
                    let line = format!("{}: {x}", path.display());
                    if !w.contains(&line) {
                        w.push(line);
                    }
                }
                Ok((path, l.model))
            }
            Err(e) => self.fail(key, format!("robot file does not load: {e}")),
        }
    }
}

/// Declares a family of configurable kinds (the plants, the control laws) from one line per
/// kind, so adding a kind is its own module plus one line in the family's registry:
///
/// ```text
/// kinds! {
///     family "plant", trait PlantConfig, context PlantContext;
///     /// The `plant.kind` values.
///     pub enum PlantKind;
///     /// The validated plant: one variant per kind.
///     pub enum PlantModel;
///     /// The `[plant]` table: the keys all kinds share and one table per kind.
///     pub struct RawPlant { pub kind: PlantKind, pub step: Option<f64> };
///     two_mass => TwoMass(TwoMassSpec),
/// }
/// ```
///
/// Each line `name => Variant(Spec)` declares `pub mod name;` and, by convention, that module
/// has `pub struct Table` (the `[<family>.name]` keys, deserialised), `pub fn validate(Option<Table>,
/// &Check, &Context) -> Result<Spec, ConfigError>` and `Spec: Trait`. The macro adds `Variant`
/// to the kind enum (spelt `name` in TOML: variants are the CamelCase of their names), an
/// optional `name` table to the raw struct (beside the shared keys given) and
/// `Variant(name::Spec)` to the spec enum. `Raw::validate_kind` refuses the tables of the kinds
/// not chosen and validates the chosen one;
/// `Spec::kind` and `Spec::config` (the spec as `&dyn Trait`) let callers stay ignorant of the
/// kinds.
#[macro_export]
macro_rules! kinds {
    (
        family $family:literal, trait $Trait:ident, context $Cx:ty;
        $(#[$kind_meta:meta])* pub enum $Kind:ident;
        $(#[$spec_meta:meta])* pub enum $Spec:ident;
        $(#[$tables_meta:meta])* pub struct $Tables:ident {
            $( $(#[$fmeta:meta])* pub $field:ident : $fty:ty ),* $(,)?
        };
        $( $name:ident => $Variant:ident($SpecTy:ident) ),+ $(,)?
    ) => {
        $( pub mod $name; )+

        $(#[$kind_meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
        #[serde(rename_all = "snake_case")]
        pub enum $Kind {
            $(
                /// A kind of the family, written in TOML as its module's name (`name` gives it).
                $Variant,
            )+
        }

        impl $Kind {
            /// Every kind, in registry order.
            pub const ALL: &'static [$Kind] = &[$( $Kind::$Variant, )+];
            /// The kind as written in TOML.
            pub fn name(self) -> &'static str {
                match self { $( $Kind::$Variant => stringify!($name), )+ }
            }
        }

        $(#[$tables_meta])*
        #[derive(Debug, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $Tables {
            $( $(#[$fmeta])* pub $field: $fty, )*
            $(
                /// A kind's own table (`[<family>.<name>]`) if the file has one; only the chosen
                /// kind may have one.
                pub $name: Option<$name::Table>,
            )+
        }

        impl $Tables {
            /// Validate the table of `kind` (absent = its defaults); the tables of other kinds
            /// are refused by name. The tables are taken, the shared keys left.
            pub fn validate_kind(
                &mut self,
                kind: $Kind,
                check: &$crate::check::Check,
                cx: &$Cx,
            ) -> Result<$Spec, $crate::check::ConfigError> {
                $(
                    if kind != $Kind::$Variant {
                        check.unused(
                            concat!($family, ".", stringify!($name)),
                            self.$name.is_some(),
                            concat!("by this ", $family, " kind"),
                        )?;
                    }
                )+
                match kind {
                    $( $Kind::$Variant => Ok($Spec::$Variant($name::validate(self.$name.take(), check, cx)?)), )+
                }
            }
        }

        $(#[$spec_meta])*
        #[derive(Debug, Clone, serde::Serialize)]
        #[serde(tag = "kind", rename_all = "snake_case")]
        pub enum $Spec {
            $(
                /// A kind's validated settings.
                $Variant($name::$SpecTy),
            )+
        }

        impl $Spec {
            /// The kind these settings are of.
            pub fn kind(&self) -> $Kind {
                match self { $( $Spec::$Variant(_) => $Kind::$Variant, )+ }
            }
            /// The kind's own configuration behind the family's interface.
            pub fn config(&self) -> &dyn $Trait {
                match self { $( $Spec::$Variant(s) => s, )+ }
            }
        }
    };
}
