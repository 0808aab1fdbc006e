//! The controller's model check (`law::model_check`) on a shipped scenario: estimates adopted
//! at their sample, bad ones refused, and a set unstable on the adopted estimate refused.
use evoloop::config::{Overrides, Scenario};
use evoloop::law::model_check::ModelCheck;
use evoloop::msg::ModelEstimate;

fn two_mass() -> Scenario {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("config/two_mass/two_mass_indirect.toml");
    Scenario::load(&path, &Overrides::default()).unwrap()
}

fn estimate_at(value: f64, apply_at_seq: u64) -> ModelEstimate {
    ModelEstimate {
        value,
        apply_at_seq,
        ..Default::default()
    }
}

#[test]
fn estimates_are_adopted_at_their_sample_and_bad_ones_keep_the_model() {
    let scn = two_mass();
    let mut mc = ModelCheck::new(&scn.plant.model).expect("the two-mass has a spring");
    mc.offer(&estimate_at(1.5, 101));
    mc.offer(&estimate_at(f64::NAN, 101));
    mc.offer(&estimate_at(1.8, 201));
    assert!(mc.due(100).is_none(), "not due yet");
    let m = mc.due(101).expect("1.5 adopted, the NaN refused");
    assert_eq!(Some(m), scn.linear_model_at(1.5));
    assert_eq!((mc.report().adopted, mc.report().refused), (1, 1));
    assert_eq!(mc.report().last_adopted, Some(1.5));
    mc.offer(&estimate_at(-1.0, 150));
    assert!(mc.due(150).is_none(), "a negative spring is refused");
    assert_eq!(mc.due(201), scn.linear_model_at(1.8));
    assert_eq!(mc.report().last_adopted, Some(1.8));
    assert_eq!(mc.report().refused, 2);
}

/// A gain set that stabilises the configured model (two_mass_indirect leaves
/// `plant.two_mass.spring` at 1) but not the plant at the estimated spring is refused once
/// that estimate is adopted, with its own reason, and the loop keeps its set; before, the
/// same set is accepted.
#[test]
fn a_set_unstable_on_the_adopted_estimate_is_refused_and_the_loop_keeps_its_set() {
    use evoloop::law::ControlCycle;
    use evoloop::msg::{ParamCode, ParamSet, PlantState, Telemetry};
    let scn = two_mass();
    let configured = scn.linear_model().unwrap();
    let stiff = scn.linear_model_at(2.0).unwrap();
    // A set from the configured bounds on which the two models disagree.
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let b = scn.bounds();
    let gains = (0..100_000)
        .map(|_| {
            (0..5)
                .map(|i| rng.gen_range(b.lower[i]..=b.upper[i]))
                .collect::<Vec<f64>>()
        })
        .find(|k| configured.stabilised_by(k) && !stiff.stabilised_by(k))
        .expect("a set stable at k = 1 but not at k = 2");
    let set = ParamSet::new(1, 0, scn.controller.param_kind(), &gains);
    let outcome = |estimate: Option<f64>| {
        let mut cycle =
            ControlCycle::new(scn.build_controller(), scn.reference.clone(), scn.bounds())
                .with_stability_check(scn.linear_model());
        let mut mc = ModelCheck::new(&scn.plant.model).unwrap();
        if let Some(k) = estimate {
            mc.offer(&estimate_at(k, 0));
        }
        if let Some(m) = mc.due(0) {
            cycle.check_on(m);
        }
        cycle.offer(&set);
        let e = cycle.step(&PlantState::default(), &mut Telemetry::default());
        (e.map(|e| e.code), cycle.version())
    };
    assert_eq!(outcome(None), (Some(ParamCode::Accepted), 1));
    assert_eq!(
        outcome(Some(2.0)),
        (Some(ParamCode::RejectedUnstableOnEstimate), 0)
    );
}
