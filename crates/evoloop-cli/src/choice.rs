//! The library crates' enums as a flag's values. The libraries know nothing of clap: each such
//! enum lists its values (`ALL`) and spells them (`name`, as its files and reports do), and this
//! gives clap those names, so that `--help` lists them and a wrong value is refused with the
//! list (`[possible values: sleep, spin, hybrid]`); where the library describes each value
//! (`HotPath::what`), `--help` shows that beside its name.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};

/// An enum whose values a flag takes by name.
pub trait Choice: Copy + Send + Sync + 'static {
    /// Every value, in the order `--help` lists them.
    const ALL: &'static [Self];
    /// The value's name on the command line.
    fn name(self) -> &'static str;
    /// What the value means, where its library says it in a line.
    fn help(self) -> Option<&'static str> {
        None
    }
}

/// clap's parser of a `Choice`: its names, each read back as its value.
pub fn choice<T: Choice>() -> impl TypedValueParser<Value = T> {
    let values = T::ALL.iter().map(|t| {
        let value = PossibleValue::new(t.name());
        match t.help() {
            Some(help) => value.help(help),
            None => value,
        }
    });
    PossibleValuesParser::new(values).map(|s| {
        *T::ALL
            .iter()
            .find(|t| t.name() == s)
            .expect("clap passes on only the names it was given")
    })
}

/// `Choice` for enums that have `ALL` and a name method of their own (`name` unless given).
macro_rules! choices {
    ($($t:ty $(=> $name:ident)?),* $(,)?) => {$(
        impl Choice for $t {
            const ALL: &'static [Self] = &<$t>::ALL;
            fn name(self) -> &'static str {
                choices!(@name self $($name)?)
            }
        }
    )*};
    (@name $v:ident) => { $v.name() };
    (@name $v:ident $name:ident) => { $v.$name() };
}

choices!(
    evoloop_rt::WaitKind,
    evoloop_rkgnn::model::Weighing,
    evoloop_rkgnn::model::Start,
    evoloop_identify::identify::StageKind,
    evoloop_identify::identify::excitation::TrajectoryKind,
    evoloop_identify::rkgnn::study::JointVelocity => key,
    evoloop_run::bench::latency::Variant => arg,
    evoloop_run::bench::loop_bench::Load,
);

impl Choice for evoloop_run::bench::guard::HotPath {
    const ALL: &'static [Self] = &Self::ALL;
    fn name(self) -> &'static str {
        Self::name(self)
    }
    fn help(self) -> Option<&'static str> {
        Some(self.what())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each value's name reads back as that value, and no two values share a name.
    fn round_trips<T: Choice + PartialEq + std::fmt::Debug>() {
        let cmd = clap::Command::new("t").arg(clap::Arg::new("v"));
        for t in T::ALL {
            let got = choice::<T>()
                .parse_ref(&cmd, None, std::ffi::OsStr::new(t.name()))
                .unwrap();
            assert_eq!(got, *t);
        }
        let mut names: Vec<_> = T::ALL.iter().map(|t| t.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), T::ALL.len());
        assert!(choice::<T>()
            .parse_ref(&cmd, None, std::ffi::OsStr::new("no-such-value"))
            .is_err());
    }

    #[test]
    fn every_choice_reads_its_names_back_and_refuses_others() {
        round_trips::<evoloop_rt::WaitKind>();
        round_trips::<evoloop_rkgnn::model::Weighing>();
        round_trips::<evoloop_rkgnn::model::Start>();
        round_trips::<evoloop_identify::identify::StageKind>();
        round_trips::<evoloop_identify::identify::excitation::TrajectoryKind>();
        round_trips::<evoloop_identify::rkgnn::study::JointVelocity>();
        round_trips::<evoloop_run::bench::latency::Variant>();
        round_trips::<evoloop_run::bench::loop_bench::Load>();
        round_trips::<evoloop_run::bench::guard::HotPath>();
    }
}
