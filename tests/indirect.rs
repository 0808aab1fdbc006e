//! The indirect scheme live on the maglev (lockstep, seeded): while a load is added to the ball
//! the optimiser's model estimate follows the true mass, better sets are accepted, and the cost
//! per repetition is at least 10 % below the frozen run's after the change and no higher before
//! it; the run is reproducible. In realtime an epoch longer than the state queue loses no sample.

mod common;
use common::*;
use std::path::Path;

#[test]
fn the_optimiser_tracks_the_load_and_is_ten_percent_cheaper_than_frozen_after_it_and_no_worse_before(
) {
    let _alone = alone();
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/maglev/maglev_indirect.toml");
    let tmp = tempfile::tempdir().unwrap();
    let tuned = tmp.path().join("tuned");
    let frozen = tmp.path().join("frozen");
    assert_ok(&run(&cfg, &tuned, "ind", &[]));
    assert_ok(&run(&cfg, &frozen, "frozen", &["--optimiser", "off"]));
    let s = json(&tuned.join("summary.json"));
    let f = json(&frozen.join("summary.json"));
    let err = s["model_estimate_error"].as_f64().unwrap();
    assert!(
        err.abs() < 0.05,
        "final mass estimate off by {:.1} %",
        100.0 * err
    );
    assert!((s["model_true_final"].as_f64().unwrap() - 0.255).abs() < 1e-12);
    assert!(
        s["accepted_versions"].as_u64().unwrap() >= 1,
        "no better set accepted"
    );
    assert_eq!(s["rejected_versions"], 0);
    assert_eq!(f["accepted_versions"], 0);
    // Lockstep: the plant waits for the optimiser's epochs, so the estimator sees every sample.
    assert_eq!(s["optimiser_samples_missed"], 0);
    let (before, frozen_before) = (
        s["cost_before_change"].as_f64().unwrap(),
        f["cost_before_change"].as_f64().unwrap(),
    );
    assert!(
        before <= frozen_before,
        "before the change: tuned {before} vs frozen {frozen_before}"
    );
    let (after, frozen_after) = (
        s["cost_after_change"].as_f64().unwrap(),
        f["cost_after_change"].as_f64().unwrap(),
    );
    assert!(
        after <= 0.9 * frozen_after,
        "cost per repetition after adaptation {after} vs frozen {frozen_after}"
    );
    // Why: the frozen gains lose the ball onto its catcher (-5 mm) once the load passes about
    // 250 g; the re-tuned controller keeps it within 1.5 mm of the square wave's -2 mm low.
    let lowest = |dir: &Path| {
        Csv::read(&dir.join("run.csv"))
            .col("y0")
            .into_iter()
            .fold(f64::INFINITY, f64::min)
    };
    assert!(lowest(&frozen) < -4.9, "the frozen run kept the ball");
    assert!(lowest(&tuned) > -3.5, "the tuned run: {}", lowest(&tuned));
    // The report's own frozen comparison (in-process simulation with the optimiser off) is the
    // frozen run of the processes exactly: lockstep is bit-identical to the simulation.
    assert_eq!(
        s["cost_after_change_frozen"].as_f64().unwrap(),
        frozen_after
    );
    assert_eq!(s["cost_per_repetition_frozen"], f["cost_per_repetition"]);
    // The estimate follows the load (portions at 10, 13 and 16 s; the least squares forget with
    // 0.995 per 10 ms update, a 2 s time constant): within 5 % from 4 s after the last on.
    let est = Csv::read(&tuned.join("estimates.csv"));
    let (t, e, tr) = (est.col("t"), est.col("estimate"), est.col("true"));
    for i in 0..t.len() {
        if t[i] >= 20.0 {
            assert!(
                ((e[i] - tr[i]) / tr[i]).abs() < 0.05,
                "t = {}: {} vs {}",
                t[i],
                e[i],
                tr[i]
            );
        }
    }
    assert_plotted(&tuned.join("indirect.png"));
    assert!(tuned.join("repetitions.csv").is_file());
    // Reproducible: paced by simulated time, the same seed gives the same run.
    let again = tmp.path().join("again");
    assert_ok(&run(&cfg, &again, "ind2", &[]));
    assert_eq!(
        std::fs::read(tuned.join("run.csv")).unwrap(),
        std::fs::read(again.join("run.csv")).unwrap()
    );
}

/// The encoder on the driven mass (config/two_mass/two_mass_indirect_collocated.toml): the filter with
/// a state noise keeps its error poles off the antiresonance, and the scheme beats the frozen
/// gains after the drift by far. Measured on seed 1: 1831 against 5466 (-66 %); the same file
/// without `state_noise` 6903 against 5658, one set published, which fails this test.
#[test]
fn the_two_mass_optimiser_on_a_collocated_encoder_beats_the_frozen_gains() {
    let _alone = alone();
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("config/two_mass/two_mass_indirect_collocated.toml");
    let tmp = tempfile::tempdir().unwrap();
    let (tuned, frozen) = (tmp.path().join("tuned"), tmp.path().join("frozen"));
    assert_ok(&run(&cfg, &tuned, "tmcol", &[]));
    assert_ok(&run(&cfg, &frozen, "tmcolf", &["--optimiser", "off"]));
    let s = json(&tuned.join("summary.json"));
    let f = json(&frozen.join("summary.json"));
    assert_eq!(s["rejected_versions"], 0);
    assert!(s["accepted_versions"].as_u64().unwrap() >= 2, "{s}");
    let (a, b) = (
        s["cost_after_change"].as_f64().unwrap(),
        f["cost_after_change"].as_f64().unwrap(),
    );
    assert!(a < 0.6 * b, "after the drift: tuned {a} vs frozen {b}");
    let cm = &s["check_model"];
    assert_eq!(cm["filters_designed"], cm["adopted"], "{cm}");
    assert_eq!(cm["filters_refused"], 0);
}

#[test]
fn the_two_mass_optimiser_tracks_the_spring_and_beats_the_frozen_gains() {
    let _alone = alone();
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/two_mass/two_mass_indirect.toml");
    let tmp = tempfile::tempdir().unwrap();
    let (tuned, frozen) = (tmp.path().join("tuned"), tmp.path().join("frozen"));
    assert_ok(&run(&cfg, &tuned, "tmind", &[]));
    assert_ok(&run(&cfg, &frozen, "tmfro", &["--optimiser", "off"]));
    let s = json(&tuned.join("summary.json"));
    let f = json(&frozen.join("summary.json"));
    assert!(s["model_estimate_error"].as_f64().unwrap().abs() < 0.05);
    assert!(s["accepted_versions"].as_u64().unwrap() >= 1);
    assert_eq!(
        s["rejected_versions"], 0,
        "the optimiser only sends sets the controller accepts"
    );
    let (a, b) = (
        s["cost_after_change"].as_f64().unwrap(),
        f["cost_after_change"].as_f64().unwrap(),
    );
    assert!(a < b, "after the drift: tuned {a} vs frozen {b}");
    // The controller checked the sets on the streamed estimate too (adopted at 10 Hz), and
    // ended on the drifted spring's model, not only the configured one.
    let cm = &s["check_model"];
    assert!(cm["adopted"].as_u64().unwrap() > 700, "{cm}");
    assert_eq!(cm["refused"], 0);
    // The law runs on its Kalman filter, designed again on each estimate it adopted.
    assert_eq!(cm["filters_designed"], cm["adopted"], "{cm}");
    assert_eq!(cm["filters_refused"], 0);
    let last = cm["last_adopted"].as_f64().unwrap();
    assert!((last - 2.0).abs() < 0.05 * 2.0, "{cm}");
    // The estimator reads the noisy, quantised position (noise 5e-4, 1e-4 per count) and the
    // command. Once settled, before the ramp of k (0.5 at 20 s to 2 at 40 s) and after it, the
    // estimate is within three of its own standard deviations (from the measured noise level and
    // the data it keeps), and those are at most 1.8 % of k (the design precision is 1 %; while
    // the plant rests 5 s between set-point changes the information fades with a 5 s time
    // constant, so the deviation grows by up to e^0.5 = 1.65 before the next transient).
    let est = Csv::read(&tuned.join("estimates.csv"));
    let (t, e, sd, tr) = (
        est.col("t"),
        est.col("estimate"),
        est.col("std"),
        est.col("true"),
    );
    let mut checked = 0;
    for i in 0..t.len() {
        if (5.0..20.0).contains(&t[i]) || t[i] >= 45.0 {
            assert!(
                (e[i] - tr[i]).abs() <= 3.0 * sd[i] && sd[i] <= 0.018 * tr[i],
                "t = {}: {} vs {} (std {})",
                t[i],
                e[i],
                tr[i],
                sd[i]
            );
            checked += 1;
        }
    }
    assert!(checked > 400, "{checked} estimates checked");
}

#[test]
fn a_killed_optimiser_leaves_the_loop_running_and_a_restarted_one_rejoins_and_tunes_on() {
    let _alone = alone();
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("config/maglev/maglev_indirect.toml"),
    )
    .unwrap()
    .replace("duration = 30.0", "duration = 60.0");
    let cfg = write(tmp.path(), "kill.toml", &text);
    let out = tmp.path().join("out");
    let (prefix, run_id) = unique("optkill");
    let mut child = spawn_run(&cfg, &out, &prefix, &run_id);
    let pid = process_named(&run_id, "evoloop-optimiser");
    std::thread::sleep(std::time::Duration::from_millis(600));
    // SAFETY: plain syscall on a process this test started (through the launcher).
    unsafe { libc::kill(pid as i32, libc::SIGKILL) };
    let status = child.wait().unwrap();
    assert!(
        status.success(),
        "the run must survive its optimiser: {status}"
    );
    let s = json(&out.join("summary.json"));
    assert_eq!(s["optimiser_restarts"], 1);
    assert_eq!(s["samples"], 60_000, "the loop ran every sample");
    assert_eq!(
        s["rejected_versions"], 0,
        "the rejoined optimiser continued the versions"
    );
    // The restarted optimiser tuned on: its own report has epochs, its sets were accepted.
    let o = json(&out.join("optimiser.json"));
    let epochs = o["epochs"].as_array().unwrap();
    assert!(!epochs.is_empty(), "no tuning after the restart");
    let journal = std::fs::read_to_string(out.join("published.jsonl")).unwrap();
    let versions: Vec<u64> = journal
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).unwrap()["version"]
                .as_u64()
                .unwrap()
        })
        .collect();
    assert!(
        versions.windows(2).all(|w| w[1] == w[0] + 1),
        "{versions:?}"
    );
    // Every journalled set reached the controller and was accepted, except possibly the last one
    // when the kill fell between journalling it and sending it.
    let accepted = s["accepted_versions"].as_u64().unwrap() as usize;
    assert!(
        accepted == versions.len() || accepted + 1 == versions.len(),
        "{accepted} accepted of {versions:?}"
    );
    forget_prefix(&prefix);
}

/// `evoloop run <indirect scenario> --seeds`: one run per seed, the study's per-seed numbers are
/// those runs' own summaries, and its sentences follow its paired tests.
#[test]
fn a_multi_seed_run_compares_the_indirect_scheme_with_the_frozen_controller() {
    let _alone = alone();
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/two_mass/two_mass_indirect.toml");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("study");
    assert_ok(&run(
        &cfg,
        &out,
        "seeds",
        &["--seeds", "3,5", "--duration", "50"],
    ));
    let rows = Csv::read(&out.join("seeds.csv"));
    assert_eq!(rows.col("seed"), vec![3.0, 5.0]);
    for (i, seed) in [3, 5].iter().enumerate() {
        let s = json(&out.join(format!("seed-{seed}/summary.json")));
        assert_eq!(s["seed"], *seed);
        assert_eq!(
            rows.col("cost_after")[i],
            s["cost_after_change"].as_f64().unwrap()
        );
        assert_eq!(
            rows.col("cost_after_frozen")[i],
            s["cost_after_change_frozen"].as_f64().unwrap()
        );
        assert_eq!(
            rows.col("cost_before_frozen")[i],
            s["cost_before_change_frozen"].as_f64().unwrap()
        );
    }
    let st = json(&out.join("study.json"));
    for c in st["comparisons"].as_array().unwrap() {
        let p = c["wilcoxon"]["p_two_sided"].as_f64().unwrap();
        let sentence = c["sentence"].as_str().unwrap();
        // Two seeds cannot show a difference at 5 % (the smallest exact p is 0.5).
        assert!(
            p >= 0.5 && sentence.starts_with("No difference"),
            "{p}: {sentence}"
        );
    }
    assert!(out.join("study.md").is_file());
    assert_plotted(&out.join("study_cost.png"));

    // Only an indirect scenario has a frozen comparison to make.
    let plain = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/two_mass/two_mass.toml");
    let o = run(
        &plain,
        &tmp.path().join("plain"),
        "seedsx",
        &["--seeds", "1..3"],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("optimiser.mode"));
}

/// Realtime: epochs run on a worker thread of the optimiser process while its receiving thread
/// goes on feeding the estimator, so an epoch lasting several times the state queue (264
/// samples, 0.264 s at 1 kHz; before, epochs ran on the receiving thread and what overflowed the
/// queue was lost) loses no sample. 1500 evaluations an epoch take about 1.4 s here.
#[test]
fn in_realtime_an_epoch_longer_than_the_state_queue_loses_no_sample() {
    let _alone = alone();
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("config/maglev/maglev_indirect.toml"),
    )
    .unwrap();
    let long = text.replace("epoch_evaluations = 150 ", "epoch_evaluations = 1500 ");
    assert_ne!(long, text);
    let cfg = write(tmp.path(), "long.toml", &long);
    let out = tmp.path().join("out");
    assert_ok(&run(
        &cfg,
        &out,
        "indrt",
        &["--mode", "realtime", "--duration", "5"],
    ));
    let o = json(&out.join("optimiser.json"));
    let epochs = o["epochs"].as_array().unwrap();
    let longest = epochs
        .iter()
        .map(|e| e["wall_s"].as_f64().unwrap())
        .fold(0.0, f64::max);
    let queue = evoloop::ipc::Topic::State.max_buffer() as f64 * 1e-3;
    assert!(
        longest > queue,
        "the premise: an epoch ({longest} s) longer than the state queue ({queue} s)"
    );
    let s = json(&out.join("summary.json"));
    assert_eq!(
        s["optimiser_samples_missed"], 0,
        "{}",
        s["optimiser_samples_missed"]
    );
    // It saw the run's samples (the first after it joined and every one after).
    assert!(
        o["states_seen"].as_u64().unwrap() >= 4_900,
        "{}",
        o["states_seen"]
    );
}

/// The general scheme (any linear single-input plant, no plant-specific code) on the DC motor
/// whose inertia triples at 20 s, over 8 seeds (the encoder noise's): after the change the
/// tuned PID costs less per repetition than the frozen configured set on every seed, with the
/// study's paired test saying so, and less than the strongest frozen baseline too: the set the
/// scheme itself had tuned for the nominal motor, kept frozen from the start (Wilcoxon on the
/// same seeds). The estimate ends on the true input gain, and the controller checks sets on the
/// estimated transfer function it adopts.
#[test]
fn the_general_scheme_beats_the_frozen_pid_and_the_nominally_tuned_one_after_the_motor_s_load_change(
) {
    let _alone = alone();
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/linear/lti_motor_indirect.toml");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("study");
    assert_ok(&run(
        &cfg,
        &out,
        "lmseeds",
        &["--seeds", "1..8", "--duration", "40"],
    ));
    let text = std::fs::read_to_string(&cfg).unwrap();
    let (mut tuned, mut frozen, mut nominal_best) = (vec![], vec![], vec![]);
    for seed in 1..=8u64 {
        let dir = out.join(format!("seed-{seed}"));
        let s = json(&dir.join("summary.json"));
        let err = s["model_estimate_error"].as_f64().unwrap();
        assert!(err.abs() < 0.01, "seed {seed}: input gain off by {err}");
        // The controller checked every set on the estimates it adopted, in the cycle, without
        // allocating, and the optimiser sent none it would refuse.
        assert!(
            s["check_model"]["adopted"].as_u64().unwrap() > 100,
            "{}",
            s["check_model"]
        );
        assert_eq!(s["cycle_allocations"]["allocations"], 0);
        assert_eq!(s["rejected_versions"], 0);
        tuned.push(s["cost_after_change"].as_f64().unwrap());
        frozen.push(s["cost_after_change_frozen"].as_f64().unwrap());
        // The last set published before the change, frozen from the start on the same seed.
        let o = json(&dir.join("optimiser.json"));
        let before: Vec<&serde_json::Value> = o["published"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|p| p["at"].as_f64().unwrap() < 20.0)
            .collect();
        let values = &before.last().expect("a set tuned before the change")["values"];
        let cfg_b = write(
            tmp.path(),
            &format!("nominal-{seed}.toml"),
            &text.replace("params = [20.0, 0.02, 0.02]", &format!("params = {values}")),
        );
        let dir_b = tmp.path().join(format!("nominal-{seed}"));
        let seed_s = seed.to_string();
        assert_ok(&run(
            &cfg_b,
            &dir_b,
            "lmnom",
            &["--optimiser", "off", "--seed", &seed_s, "--duration", "40"],
        ));
        nominal_best.push(
            json(&dir_b.join("summary.json"))["cost_after_change"]
                .as_f64()
                .unwrap(),
        );
    }
    for i in 0..8 {
        assert!(
            tuned[i] < frozen[i],
            "seed {}: {} vs {}",
            i + 1,
            tuned[i],
            frozen[i]
        );
    }
    let st = json(&out.join("study.json"));
    let after = st["comparisons"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["phase"] == "after the change")
        .expect("the after-change comparison");
    assert!(
        after["wilcoxon"]["p_two_sided"].as_f64().unwrap() < 0.05
            && after["sentence"].as_str().unwrap().contains("lower"),
        "{after}"
    );
    let w = evoloop::stats::wilcoxon(&tuned, &nominal_best);
    assert!(
        w.a_lower > w.a_higher && w.p_two_sided < 0.05,
        "tuned {tuned:?} vs nominally tuned and frozen {nominal_best:?}: p {}",
        w.p_two_sided
    );
}
