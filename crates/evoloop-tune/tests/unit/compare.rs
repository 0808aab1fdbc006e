use evoloop_tune::compare::*;

/// A run of `alg` on `seed` whose best cost after each of 10 experiments is `best`, with
/// `aborts` aborts at its first experiment.
fn run(alg: &str, seed: u64, best: &[f64], baseline: f64, aborts: u32) -> Run {
    let mut best = best.to_vec();
    best.resize(10, *best.last().unwrap());
    Run {
        algorithm: alg.into(),
        seed,
        final_cost: *best.last().unwrap(),
        best,
        experiments: 10,
        aborts: vec![aborts; 10],
        baseline_cost: baseline,
        to_target: None,
        to_best: None,
        settle_repetitions: 0,
        plant_seconds: 0.0,
        settle_share: 0.0,
        wall_seconds: 0.0,
    }
}

fn summaries(runs: &[Run], seeds: &[u64]) -> Vec<Summary> {
    ["ga", "x"]
        .iter()
        .map(|a| summarise(a, runs, seeds, 10))
        .collect()
}

/// The verdicts follow the numbers: a GA that improves gives the yardstick (x meets the goal
/// with 1 experiment against its 10 and no abort; with two aborts it is fast, not safe); a GA
/// that never improves on its start makes the speed part void, and the report says so.
#[test]
fn the_goal_is_judged_from_the_numbers_and_a_void_yardstick_is_named() {
    let seeds: Vec<u64> = (1..=20).collect();
    let improving: Vec<Run> = seeds
        .iter()
        .flat_map(|&s| {
            let mut ga: Vec<f64> = (0..10).map(|k| 100.0 - k as f64).collect();
            ga[9] = 50.0;
            [run("ga", s, &ga, 100.0, 1), run("x", s, &[50.0], 100.0, 0)]
        })
        .collect();
    let mut runs = improving.clone();
    for r in &mut runs {
        r.to_target = r.best.iter().position(|&b| b <= 50.5).map(|i| i + 1);
    }
    let md = goal(&summaries(&runs, &seeds));
    assert!(md.contains("- x: meets it: 1 [1, 1] experiments"), "{md}");
    assert!(!md.contains("no yardstick"), "{md}");
    runs[1].aborts = vec![2; 10];
    let md = goal(&summaries(&runs, &seeds));
    assert!(md.contains("- x: fast enough, not safe enough"), "{md}");
    // The GA never improves: its final cost is its start's.
    for r in runs.iter_mut().filter(|r| r.algorithm == "ga") {
        r.best = vec![100.0; 10];
        r.final_cost = 100.0;
        r.to_target = Some(1);
    }
    let md = goal(&summaries(&runs, &seeds));
    assert!(
        md.contains("improved on its start on 0 of 20 seeds"),
        "{md}"
    );
    assert!(
        md.contains("- x: not safe enough (speed: no yardstick)"),
        "{md}"
    );
}
