//! The library crates' enums as a flag's values. The libraries know nothing of clap: each such
//! enum lists its values (`ALL`) and spells them (`name`, as its files and reports do), and
//! `choice` gives clap those names, so that `--help` lists them and a wrong value is refused
//! with the list (`[possible values: sleep, spin, hybrid]`); `described` adds a line per value
//! where the library has one (`HotPath::what`).

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};

/// clap's parser of an enum whose values are `all`, each spelt by `name`.
pub fn choice<T: Copy + Send + Sync + 'static>(
    all: &'static [T],
    name: fn(T) -> &'static str,
) -> impl TypedValueParser<Value = T> {
    described(all, name, |_| None)
}

/// `choice` with each value's meaning in `--help`, where `help` gives one.
pub fn described<T: Copy + Send + Sync + 'static>(
    all: &'static [T],
    name: fn(T) -> &'static str,
    help: fn(T) -> Option<&'static str>,
) -> impl TypedValueParser<Value = T> {
    let values = all.iter().map(move |&t| {
        let value = PossibleValue::new(name(t));
        match help(t) {
            Some(h) => value.help(h),
            None => value,
        }
    });
    PossibleValuesParser::new(values).map(move |s| {
        *all.iter()
            .find(|&&t| name(t) == s)
            .expect("clap passes on only the names it was given")
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use evoloop_identify::identify::{excitation::TrajectoryKind, StageKind};
    use evoloop_identify::rkgnn::study::JointVelocity;
    use evoloop_rkgnn::model::{Start, Weighing};
    use evoloop_rt::WaitKind;
    use evoloop_run::bench::{guard::HotPath, latency::Variant, loop_bench::Load};

    /// Each value's name reads back as that value, no two values share a name, and another
    /// name is refused.
    fn round_trips<T>(all: &'static [T], name: fn(T) -> &'static str)
    where
        T: Copy + Send + Sync + PartialEq + std::fmt::Debug + 'static,
    {
        let cmd = clap::Command::new("t").arg(clap::Arg::new("v"));
        let parse = |s: &str| choice(all, name).parse_ref(&cmd, None, std::ffi::OsStr::new(s));
        for &t in all {
            assert_eq!(parse(name(t)).unwrap(), t);
        }
        let mut names: Vec<_> = all.iter().map(|&t| name(t)).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), all.len());
        assert!(parse("no-such-value").is_err());
    }

    #[test]
    fn every_choice_reads_its_names_back_and_refuses_others() {
        round_trips(&WaitKind::ALL, WaitKind::name);
        round_trips(&Weighing::ALL, Weighing::name);
        round_trips(&Start::ALL, Start::name);
        round_trips(&StageKind::ALL, StageKind::name);
        round_trips(&TrajectoryKind::ALL, TrajectoryKind::name);
        round_trips(&JointVelocity::ALL, JointVelocity::key);
        round_trips(&Variant::ALL, Variant::arg);
        round_trips(&Load::ALL, Load::name);
        round_trips(&HotPath::ALL, HotPath::name);
    }
}
