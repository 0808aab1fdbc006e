use evoloop_schemes::indirect::EpochRecord;

/// The smallest budget the scenario accepts (12, the maglev GA's) still runs one generation
/// of DE's 15: an epoch never ends unscored.
#[test]
fn a_budget_below_des_population_still_runs_one_generation() {
    let sphere = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>();
    let mut epochs =
        evoloop_schemes::indirect::DeEpochs::within(vec![-1.0; 2], vec![1.0; 2], 1, 1, 12);
    let (best, cost) = epochs.run(&[], &sphere);
    assert_eq!(best.len(), 2);
    assert!(cost.is_finite(), "{cost}");
}

#[test]
fn samples_the_estimator_never_saw_are_counted() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/maglev/maglev_indirect.toml");
    let scn = evoloop_scenario::config::Scenario::load(
        &path,
        &evoloop_scenario::config::Overrides::default(),
    )
    .unwrap();
    let mut ind = evoloop_schemes::indirect::Indirect::new(&scn).unwrap();
    // It starts wherever it joins the stream (a restarted optimiser), then counts the gaps.
    for seq in [40u64, 41, 42, 45, 46, 50] {
        let s = evoloop_msg::PlantState {
            seq,
            t: seq as f64 * 1e-3,
            ..Default::default()
        };
        ind.observe(&s);
    }
    assert_eq!(ind.samples_missed, 2 + 3);
}

/// An epoch whose in-service set destabilises the model (infinite cost) survives the trip
/// through optimiser.json: it was lost with the whole report before (JSON null is no f64).
#[test]
fn an_infinite_cost_reads_back_from_json() {
    let r = EpochRecord {
        t: 1.0,
        model_value: 2.0,
        best_cost: 5.0,
        in_service_cost: f64::INFINITY,
        published: Some(3),
        wall_s: 0.5,
        model: Vec::new(),
    };
    let text = serde_json::to_string(&r).unwrap();
    assert!(text.contains("\"in_service_cost\":null"), "{text}");
    let back: EpochRecord = serde_json::from_str(&text).unwrap();
    assert_eq!(back, r);
}
