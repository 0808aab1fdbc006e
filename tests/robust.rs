//! The robust-control core against independent references: the Riccati equation, the paper's
//! printed LQR gains, a dense frequency sweep, and the paper's DEFC row.

use evoloop::optim::{run, DeConfig, DifferentialEvolution};
use evoloop::plant::two_mass::Sensor;
use evoloop::robust::lqr::{lqr, riccati_residual};
use evoloop::robust::stability_radius::{hinf_norm, hinf_norm_sweep};
use evoloop::robust::{augmented, RobustProblem, Wedge};
use nalgebra::{Complex, DMatrix, DVector};
use rand::{Rng, SeedableRng};

fn diag(v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_diagonal(&DVector::from_row_slice(v))
}

#[test]
fn lqr_solves_the_riccati_equation_and_reproduces_table_9() {
    let (a, b) = augmented(1.2, Sensor::Actuated);
    let r = DMatrix::from_element(1, 1, 1.0);
    for (q, printed) in [
        (
            diag(&[10.0, 1.0, 1.0, 1.0, 10.0]),
            [1.57, 5.76, 3.23, 3.54, -3.16],
        ),
        (
            diag(&[100.0, 1.0, 1.0, 1.0, 1000.0]),
            [8.96, 20.89, 5.95, 6.54, -31.62],
        ),
    ] {
        let sol = lqr(&a, &b, &q, &r).unwrap();
        let s = &b * b.transpose();
        assert!(
            riccati_residual(&a, &s, &q, &sol.p) < 1e-9,
            "residual {}",
            sol.residual
        );
        assert!((&sol.p - sol.p.transpose()).norm() < 1e-12, "P symmetric");
        assert!(sol.p.clone().cholesky().is_some(), "P positive definite");
        for (i, want) in printed.iter().enumerate() {
            let got = (sol.k[(0, i)] * 100.0).round() / 100.0;
            assert_eq!(got, *want, "K[{i}] = {}", sol.k[(0, i)]);
        }
        let acl = &a - &b * &sol.k;
        assert!(acl.complex_eigenvalues().iter().all(|z| z.re < 0.0));
    }
}

#[test]
fn lqr_matches_the_scalar_closed_form() {
    // x' = a x + b u: P = (a + sqrt(a^2 + b^2 q / r)) r / b^2.
    for (a, b, q, r) in [
        (1.0, 1.0, 1.0, 1.0),
        (-2.0, 0.5, 3.0, 0.2),
        (0.3, 2.0, 10.0, 4.0),
    ] {
        let sol = lqr(
            &DMatrix::from_element(1, 1, a),
            &DMatrix::from_element(1, 1, b),
            &DMatrix::from_element(1, 1, q),
            &DMatrix::from_element(1, 1, r),
        )
        .unwrap();
        let p = (a + (a * a + b * b * q / r).sqrt()) * r / (b * b);
        assert!((sol.p[(0, 0)] - p).abs() < 1e-10 * p.max(1.0));
    }
}

#[test]
fn hinf_norm_agrees_with_a_dense_sweep_on_random_stable_loops() {
    let prob = RobustProblem::paper();
    let mut rng = rand::rngs::StdRng::seed_from_u64(42);
    let mut checked = 0;
    while checked < 40 {
        let k: Vec<f64> = (0..5).map(|_| rng.gen_range(-50.0..50.0)).collect();
        let acl = prob.closed_loop(&k);
        if acl.complex_eigenvalues().iter().any(|z| z.re >= -1e-3) {
            continue;
        }
        let (norm, _) = hinf_norm(&acl, &prob.e, &prob.h).unwrap();
        let sweep = hinf_norm_sweep(&acl, &prob.e, &prob.h, 4000);
        assert!(
            ((norm - sweep) / sweep).abs() < 1e-6,
            "{k:?}: level set {norm} vs sweep {sweep}"
        );
        checked += 1;
    }
}

#[test]
fn hinf_norm_of_a_first_and_second_order_system_is_analytic() {
    // 1/(s + a): norm 1/a at w = 0.
    let (n, w) = hinf_norm(
        &DMatrix::from_element(1, 1, -2.0),
        &DMatrix::from_element(1, 1, 1.0),
        &DMatrix::from_element(1, 1, 1.0),
    )
    .unwrap();
    assert!((n - 0.5).abs() < 1e-9 && w == 0.0);
    // wn^2/(s^2 + 2 z wn s + wn^2), z < 1/sqrt2: peak 1/(2 z sqrt(1 - z^2)).
    let (z, wn) = (0.1f64, 3.0f64);
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -wn * wn, -2.0 * z * wn]);
    let e = DMatrix::from_row_slice(2, 1, &[0.0, wn * wn]);
    let h = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
    let (n, w) = hinf_norm(&a, &e, &h).unwrap();
    let peak = 1.0 / (2.0 * z * (1.0 - z * z).sqrt());
    assert!((n - peak).abs() < 1e-8 * peak, "{n} vs {peak}");
    assert!((w - wn * (1.0 - 2.0 * z * z).sqrt()).abs() < 1e-3);
}

#[test]
fn the_table_9_defc_gains_are_stable_and_in_the_wedge_at_k_half() {
    let prob = RobustProblem::paper();
    let ev = prob.evaluate(&[18.49, 19.04, 47.27, 7.30, -10.54]).unwrap();
    assert!(ev.in_wedge, "{ev:?}");
    assert!(
        ev.stability_radius > 0.3 && ev.stability_radius < 0.34,
        "r_c = {}",
        ev.stability_radius
    );
    // An unstable gain set has r_c = 0.
    assert_eq!(
        prob.evaluate(&[8.96, 20.89, 5.95, 6.54, -31.62])
            .unwrap()
            .stability_radius,
        0.0
    );
}

#[test]
fn the_wedge_distance_is_zero_inside_and_euclidean_outside() {
    let w = Wedge::new(0.7, 1.0).unwrap();
    let t = w.slope();
    assert_eq!(w.distance(Complex::new(-2.0, 0.0)), 0.0);
    assert_eq!(w.distance(Complex::new(-2.0, 1.9 * t)), 0.0);
    assert!((w.distance(Complex::new(0.0, 0.0)) - 1.0).abs() < 1e-12);
    assert!((w.distance(Complex::new(-0.5, 0.0)) - 0.5).abs() < 1e-12);
    // Above the upper edge: distance to the line y = -t x.
    let (x, y) = (-3.0, 3.0 * t + 1.0);
    let d = (y + t * x) / (1.0 + t * t).sqrt();
    assert!((w.distance(Complex::new(x, y)) - d).abs() < 1e-12);
    assert!((w.distance(Complex::new(x, -y)) - d).abs() < 1e-12);
    assert!(Wedge::new(1.2, 1.0).is_err() && Wedge::new(0.7, 0.0).is_err());
}

/// The runs are deterministic (seeded, evaluated in parallel but reduced in order), so the
/// outcome is exact: every one of seeds 1..=15 reaches the literature optimum (in 389-715
/// generations when this was written); the earlier "at least 14 of 15" hid a run that moved.
#[test]
fn de_finds_the_box_constrained_optimum_on_every_one_of_15_seeds() {
    // DE/rand/1/bin with the paper's F = 0.5, CR = 0.9, NP = 100, bounds +-50 and at most 1000
    // iterations, run until it reaches the literature optimum (r_c just under 0.349, k3 on its
    // bound) instead of stopping on the diversity rule.
    let prob = RobustProblem::paper();
    let mut hits = Vec::new();
    for seed in 1..=15 {
        let mut cfg = DeConfig::paper(0.5, 0.9, prob.lower.clone(), prob.upper.clone(), seed);
        cfg.diversity_stop = false;
        let mut de = DifferentialEvolution::new(cfg).unwrap();
        let r = run(&mut de, &prob, 2, 1000, Some(-0.3489), |_| {});
        let ev = prob.evaluate(&r.best).unwrap();
        eprintln!(
            "seed {seed}: r_c {:.5}, in wedge {}, k3 {:.3}, {} generations",
            ev.stability_radius, ev.in_wedge, r.best[2], r.generations
        );
        if ev.in_wedge && ev.stability_radius >= 0.3489 {
            assert!(
                r.best[2] > 49.5,
                "k3 = {} should be at its bound",
                r.best[2]
            );
            hits.push(seed);
        }
    }
    assert_eq!(
        hits,
        (1..=15).collect::<Vec<u64>>(),
        "seeds reaching r_c >= 0.3489 in the wedge"
    );
}

#[test]
fn the_diversity_rule_stops_de_before_the_iteration_limit() {
    let prob = RobustProblem::paper();
    let f = |x: &[f64]| prob.objective(x);
    let cfg = DeConfig::paper(0.5, 0.9, prob.lower.clone(), prob.upper.clone(), 3);
    let mut de = DifferentialEvolution::new(cfg).unwrap();
    let r = run(&mut de, &f, 2, 1000, None, |_| {});
    assert_eq!(r.stopped_by, evoloop::optim::StopReason::Converged);
    assert_eq!(
        serde_json::to_value(r.stopped_by).unwrap(),
        r.stopped_by.to_string()
    );
    assert!(r.generations >= 100 && r.generations < 1000);
    assert!(prob.evaluate(&r.best).unwrap().in_wedge);
}

#[test]
fn hooke_jeeves_finds_the_minimum_of_a_bounded_quadratic() {
    use evoloop::optim::HookeJeeves;
    let f = |x: &[f64]| (x[0] - 1.0).powi(2) + 10.0 * (x[1] + 2.0).powi(2) + (x[2] - 9.0).powi(2);
    let r = HookeJeeves::default().minimise(f, &[0.0, 0.0, 0.0], &[-5.0; 3], &[5.0; 3]);
    assert!(
        (r.x[0] - 1.0).abs() < 1e-6 && (r.x[1] + 2.0).abs() < 1e-6,
        "{:?}",
        r.x
    );
    assert_eq!(r.x[2], 5.0, "the third coordinate stops on its bound");
}

#[test]
fn early_rejection_of_losing_trials_changes_nothing_in_the_run() {
    // The problem's bounded objective stops once a trial is proven worse than its target; the
    // run must be identical to one with exact values for every candidate.
    let prob = RobustProblem::paper();
    let exact = |x: &[f64]| prob.objective(x);
    let mut runs = Vec::new();
    for bounded in [false, true] {
        let cfg = DeConfig::paper(0.5, 0.9, prob.lower.clone(), prob.upper.clone(), 9);
        let mut de = DifferentialEvolution::new(cfg).unwrap();
        let r = if bounded {
            run(&mut de, &prob, 1, 150, None, |_| {})
        } else {
            run(&mut de, &exact, 1, 150, None, |_| {})
        };
        runs.push((r.best, r.value, r.history));
    }
    assert_eq!(runs[0], runs[1]);
}

#[test]
fn the_tuned_and_paper_gains_stabilise_the_plant_over_the_whole_spring_range() {
    let tuned = [13.7496, 21.7200, 49.9987, 8.1792, -8.3732];
    let paper = [18.49, 19.04, 47.27, 7.30, -10.54];
    for i in 0..=30 {
        let k = 0.5 + 1.5 * i as f64 / 30.0;
        let prob = RobustProblem::new(
            k,
            Sensor::Far,
            evoloop::robust::Perturbation::Spring,
            Wedge {
                zeta: 0.7,
                rho: 1.0,
            },
            50.0,
        );
        for g in [tuned, paper] {
            assert!(
                prob.poles(&g).iter().all(|p| p.re < 0.0),
                "unstable at k = {k} with {g:?}"
            );
        }
    }
    assert!(
        RobustProblem::paper()
            .evaluate(&tuned)
            .unwrap()
            .stability_radius
            >= 0.3489
    );
}

#[test]
fn the_spring_schedule_interpolates_and_drives_the_dynamics() {
    use evoloop::plant::two_mass::TwoMass;
    use evoloop::plant::Plant;
    let p =
        TwoMass::new(1.0, 1.0, 1.0, Sensor::Far).with_spring_schedule(&[(10.0, 0.5), (20.0, 2.0)]);
    assert_eq!(p.spring_at(0.0), 0.5);
    assert_eq!(p.spring_at(15.0), 1.25);
    assert_eq!(p.spring_at(99.0), 2.0);
    let x = [1.0, 0.0, 0.0, 0.0];
    let mut dx = [0.0; 4];
    p.derivative(15.0, &x, &[0.0], &mut dx);
    assert_eq!(dx[2], -1.25, "spring force on body 2 uses k(t)");
    assert_eq!(TwoMass::new(1.0, 1.0, 1.0, Sensor::Far).spring_at(5.0), 1.0);
}

#[test]
fn the_hqr_eigenvalues_match_the_schur_decomposition() {
    use evoloop::linalg::eigenvalues;
    let mut rng = rand::rngs::StdRng::seed_from_u64(17);
    let key = |z: &Complex<f64>| (z.re, z.im);
    for trial in 0..300 {
        let n = 1 + trial % 12;
        let m = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-3.0..3.0));
        let mut ours = eigenvalues(&m).expect("converges");
        let mut theirs: Vec<Complex<f64>> = m.complex_eigenvalues().iter().copied().collect();
        assert_eq!(ours.len(), n);
        // Match each of ours to the nearest of theirs (eigenvalues are unordered).
        for z in ours.drain(..) {
            let (i, d) = theirs
                .iter()
                .enumerate()
                .map(|(i, w)| (i, (w - z).norm()))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap();
            assert!(
                d < 1e-7 * (1.0 + z.norm()),
                "n = {n}: {:?} has no match",
                key(&z)
            );
            theirs.remove(i);
        }
    }
}

#[test]
fn a_radius_that_cannot_be_computed_is_an_error_not_zero() {
    use evoloop::robust::stability_radius::{stability_radius, HinfError};
    use nalgebra::DMatrix;
    let stable = DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 0.0, -2.0]);
    let eye = DMatrix::<f64>::identity(2, 2);
    // r_c of a stable loop is 1 / ||(sI - A)^-1|| = 1 here (peak at w = 0, gain 1).
    assert!((stability_radius(&stable, &eye, &eye).unwrap() - 1.0).abs() < 1e-9);
    // Not Hurwitz: r_c = 0 by definition, not an error.
    let unstable = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, -2.0]);
    assert_eq!(stability_radius(&unstable, &eye, &eye), Ok(0.0));
    // Not computable (inconsistent perturbation structure): an error, never a silent 0.
    let bad = DMatrix::<f64>::identity(3, 3);
    assert!(matches!(
        stability_radius(&stable, &bad, &eye),
        Err(HinfError::Dimensions(_))
    ));
}
