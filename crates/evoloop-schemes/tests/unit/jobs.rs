use evoloop_optim::{Job, Objective};
use evoloop_scenario::config::{Overrides, Scenario};
use evoloop_schemes::jobs::*;

/// Values of the rebuilt objective equal the original's bit for bit, for candidates that
/// keep the ball, lose it (infinite) and carry awkward bits (subnormal, -0.0, 1 ulp apart).
fn same_values(f: &dyn Objective, candidates: &[Vec<f64>]) {
    let job = f.describe().expect("describes itself");
    let g = rebuild(&job).expect("rebuilds");
    assert_eq!(g.describe(), Some(job), "the description survives the trip");
    for c in candidates {
        assert_eq!(
            f.value(c).to_bits(),
            g.value(c).to_bits(),
            "candidate {c:?}"
        );
    }
}

#[test]
fn maglev_objective_rebuilds_to_the_same_bits() {
    let mut f = evoloop_scenario::sim::maglev::Objective::fuzzy(0.5, 7);
    // A mass that is not a short decimal: the description must carry all its bits.
    f.spec.plant.mass_steps = vec![(0.0, 0.160 * (1.0 + 1.0 / 3.0) + f64::EPSILON)];
    let p = evoloop_scenario::sim::maglev::PAPER_FUZZY.to_vec();
    let mut next = p.clone();
    next[0] = f64::from_bits(p[0].to_bits() + 1);
    let mut lost = p.clone();
    lost[0] = -1e6;
    same_values(&f, &[p, next, lost]);
}

#[test]
fn two_mass_objective_rebuilds_to_the_same_bits() {
    let scn = Scenario::load(
        std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/two_mass/two_mass_indirect.toml"
        )),
        &Overrides::default(),
    )
    .expect("the shipped scenario");
    let evoloop_control::plant::PlantModel::TwoMass(plant) = &scn.plant.model else {
        panic!("a two-mass scenario")
    };
    let (_, tuner) =
        evoloop_schemes::indirect::two_mass::scheme(&scn, plant, scn.controller.tunable());
    let f = tuner.objective(0.5 + 1e-9);
    let g0 = scn.controller.tunable().gains.clone();
    let mut odd = g0.clone();
    odd[0] = -0.0;
    same_values(&f, &[g0, odd, vec![f64::MIN_POSITIVE / 4.0; 4]]);
}

#[test]
fn an_unknown_or_damaged_job_is_refused_with_its_kind() {
    let e = rebuild(&Job {
        kind: "rkgnn".into(),
        bytes: vec![],
    })
    .err()
    .expect("refused");
    assert!(
        matches!(&e, RebuildError::UnknownKind(k) if k == "rkgnn"),
        "{e}"
    );
    let e = e.to_string();
    assert!(e.contains("rkgnn") && e.contains("maglev"), "{e}");
    let e = rebuild(&Job {
        kind: "maglev".into(),
        bytes: vec![1, 2, 3],
    })
    .err()
    .expect("refused");
    assert!(matches!(&e, RebuildError::Decode(_)), "{e}");
    assert!(
        std::error::Error::source(&e).is_some(),
        "the decoder's error is kept"
    );
    let e = e.to_string();
    assert!(e.contains("maglev") && e.contains("decode"), "{e}");
}
