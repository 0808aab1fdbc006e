//! The robust-control core against independent references: the Riccati equation, the paper's
//! printed LQR gains, a dense frequency sweep, and the paper's DEFC row.

use evoloop::optim::{run, DeConfig, DifferentialEvolution};
use evoloop::plant::two_mass::Sensor;
use evoloop::robust::lqr::{lqr, riccati_residual};
use evoloop::robust::stability_radius::{hinf_norm, hinf_norm_sweep, Transfer};
use evoloop::robust::{augmented, RobustProblem, Wedge};
use nalgebra::{Complex, DMatrix, DVector};
use rand::{Rng, SeedableRng};

/// The paper's spring problem (far sensor, wedge zeta 0.7, rho 1, gain bound 50) at spring `k`.
fn spring_problem(k: f64) -> RobustProblem {
    RobustProblem::new(
        k,
        Sensor::Far,
        evoloop::robust::Perturbation::Spring,
        Wedge {
            zeta: 0.7,
            rho: 1.0,
        },
        50.0,
    )
}

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
        let (norm, _) = hinf_norm(&acl, prob.e(), prob.h()).unwrap();
        let sweep = hinf_norm_sweep(&acl, prob.e(), prob.h(), 4000);
        assert!(
            ((norm - sweep) / sweep).abs() < 1e-6,
            "{k:?}: level set {norm} vs sweep {sweep}"
        );
        checked += 1;
    }
}

/// sigma_max(H (jwI - A)^-1 E) as the gain was computed before it had its own factorisation:
/// nalgebra's complex LU, its product, the closed form for 2 x 2 and its SVD beyond.
fn nalgebra_gain(a: &DMatrix<f64>, e: &DMatrix<f64>, h: &DMatrix<f64>, w: f64) -> f64 {
    let n = a.nrows();
    let m = DMatrix::from_fn(n, n, |i, j| {
        Complex::new(-a[(i, j)], if i == j { w } else { 0.0 })
    });
    let Some(x) = m.lu().solve(&e.map(|v| Complex::new(v, 0.0))) else {
        return f64::INFINITY;
    };
    let g = h.map(|v| Complex::new(v, 0.0)) * x;
    if g.nrows() > 2 || g.ncols() > 2 {
        return g.singular_values().max();
    }
    let fro2: f64 = g.iter().map(|z| z.norm_sqr()).sum();
    if g.nrows() < 2 || g.ncols() < 2 {
        return fro2.sqrt();
    }
    let det = g[(0, 0)] * g[(1, 1)] - g[(0, 1)] * g[(1, 0)];
    let disc = (fro2 * fro2 - 4.0 * det.norm_sqr()).max(0.0);
    (0.5 * (fro2 + disc.sqrt())).sqrt()
}

/// The transfer's gain at `w`, asserted equal to `nalgebra_gain`'s to the last bit.
fn same_gain(a: &DMatrix<f64>, e: &DMatrix<f64>, h: &DMatrix<f64>, w: f64) -> f64 {
    let ours = Transfer::new(a, e, h).unwrap().gain(w);
    let theirs = nalgebra_gain(a, e, h, w);
    assert_eq!(
        ours.to_bits(),
        theirs.to_bits(),
        "{a} {e} {h} w {w}: {ours} vs {theirs}"
    );
    ours
}

#[test]
fn the_gain_is_nalgebras_lu_bit_for_bit_on_random_systems() {
    // The norm's gain evaluations solve (jwI - A) X = E in their own workspace, in nalgebra's
    // arithmetic order: the same value to the last bit on systems of 1 to 10 states, 1 to 3
    // inputs and outputs (the 2 x 2 closed form and the SVD), at DC and at random frequencies,
    // stable or not, and on the paper's closed loops.
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut compared = 0;
    for _ in 0..3000 {
        let n = rng.gen_range(1..=10);
        let (m, p) = (rng.gen_range(1..=3), rng.gen_range(1..=3));
        let mut draw = |r: usize, c: usize| DMatrix::from_fn(r, c, |_, _| rng.gen_range(-3.0..3.0));
        let (a, e, h) = (draw(n, n), draw(n, m), draw(p, n));
        let w = if rng.gen_bool(0.2) {
            0.0
        } else {
            rng.gen_range(0.0..20.0)
        };
        same_gain(&a, &e, &h, w);
        compared += 1;
    }
    // Small integer entries: ties between pivots, zero pivots, singular jwI - A (a pole hit
    // exactly: both sides say infinity).
    let mut singular = 0;
    for _ in 0..3000 {
        let n = rng.gen_range(1..=5);
        let (m, p) = (rng.gen_range(1..=2), rng.gen_range(1..=2));
        let mut draw =
            |r: usize, c: usize| DMatrix::from_fn(r, c, |_, _| f64::from(rng.gen_range(-2i32..=2)));
        let (a, e, h) = (draw(n, n), draw(n, m), draw(p, n));
        if (0..m).any(|j| e.column(j).amax() == 0.0) || (0..p).any(|i| h.row(i).amax() == 0.0) {
            continue; // the transfer drops zero columns and rows; the reference does not
        }
        let w = f64::from(rng.gen_range(0..=2));
        singular += usize::from(same_gain(&a, &e, &h, w).is_infinite());
        compared += 1;
    }
    assert!(singular > 10, "{singular} singular cases");
    // Upper Hessenberg A (the objective's closed loops are, in their basis): the factorisation
    // leaves out the rows below the subdiagonal, and must still give nalgebra's value, on real
    // entries and on small integers (ties, zero pivots, poles hit).
    let mut hessenberg_singular = 0;
    for trial in 0..3000 {
        let n = rng.gen_range(2..=8);
        let small = trial % 2 == 1;
        let mut draw = |r: usize, c: usize| {
            DMatrix::from_fn(r, c, |_, _| {
                if small {
                    f64::from(rng.gen_range(-2i32..=2))
                } else {
                    rng.gen_range(-3.0..3.0)
                }
            })
        };
        let mut a = draw(n, n);
        a.fill_lower_triangle(0.0, 2);
        let (e, h) = (draw(n, 2), draw(2, n));
        if (0..2).any(|j| e.column(j).amax() == 0.0) || (0..2).any(|i| h.row(i).amax() == 0.0) {
            continue;
        }
        let w = if small {
            f64::from(rng.gen_range(0..=2))
        } else {
            rng.gen_range(0.0..20.0)
        };
        hessenberg_singular += usize::from(same_gain(&a, &e, &h, w).is_infinite());
        compared += 1;
    }
    assert!(hessenberg_singular > 10, "{hessenberg_singular} singular");
    let prob = RobustProblem::paper();
    for _ in 0..500 {
        let k: Vec<f64> = (0..5).map(|_| rng.gen_range(-50.0..50.0)).collect();
        let acl = prob.closed_loop(&k);
        let mut g = Transfer::new(&acl, prob.e(), prob.h()).unwrap();
        // The reference gets Ê's nonzero columns and Ĥ's nonzero rows, as the transfer keeps.
        let cols: Vec<usize> = (0..5)
            .filter(|&j| prob.e().column(j).amax() > 0.0)
            .collect();
        let rows: Vec<usize> = (0..5).filter(|&i| prob.h().row(i).amax() > 0.0).collect();
        assert_eq!((cols.len(), rows.len()), (2, 2));
        let (e, h) = (prob.e().select_columns(&cols), prob.h().select_rows(&rows));
        for w in [0.0, 0.3, 1.0, 2.7] {
            assert_eq!(
                g.gain(w).to_bits(),
                nalgebra_gain(&acl, &e, &h, w).to_bits(),
                "{k:?} at {w}"
            );
            compared += 1;
        }
    }
    assert!(compared > 8500, "{compared}");
}

#[test]
fn the_objective_below_a_threshold_makes_the_decisions_of_the_exact_objective() {
    // `value_below` may stop once a candidate is proven above the threshold, returning any value
    // above it; at or below it, it is the exact value. Thresholds around each candidate's value,
    // feasible (negative) and infeasible (positive) candidates, and thresholds far from both.
    let prob = RobustProblem::paper();
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let (mut above, mut below) = (0, 0);
    for _ in 0..400 {
        let k: Vec<f64> = (0..5).map(|_| rng.gen_range(-50.0..50.0)).collect();
        let exact = prob.objective(&k);
        for t in [
            exact * (1.0 + rng.gen_range(-1e-3..1e-3)),
            exact,
            -0.3,
            -0.1,
            0.5,
        ] {
            let v = prob.objective_below(&k, t);
            if exact > t {
                assert!(v > t, "{k:?}: {v} not above {t} (exact {exact})");
                above += 1;
            } else {
                assert_eq!(v.to_bits(), exact.to_bits(), "{k:?} at {t}");
                below += 1;
            }
        }
    }
    assert!(above > 100 && below > 100, "{above} above, {below} below");
}

#[test]
fn the_objective_in_its_hessenberg_basis_changes_only_the_rounding() {
    // The objective builds each closed loop in a basis made once per problem (Hessenberg for
    // every gain vector); its poles and r_c are those of A - B K in the plant's own coordinates,
    // computed independently (nalgebra's Schur decomposition, the norm on the untransformed
    // loop), to rounding, for both sensors and both perturbation structures.
    let mut rng = rand::rngs::StdRng::seed_from_u64(23);
    let mut stable = 0;
    for (sensor, perturbation) in [
        (Sensor::Far, evoloop::robust::Perturbation::Spring),
        (Sensor::Actuated, evoloop::robust::Perturbation::Spring),
        (Sensor::Far, evoloop::robust::Perturbation::Literal),
    ] {
        let prob = RobustProblem::new(
            0.5,
            sensor,
            perturbation,
            Wedge {
                zeta: 0.7,
                rho: 1.0,
            },
            50.0,
        );
        for trial in 0..400 {
            // Half anywhere in the box (mostly unstable), half around Table 9's DEFC gains.
            let k: Vec<f64> = DEFC
                .iter()
                .map(|g| match trial % 2 {
                    0 => rng.gen_range(-50.0..50.0),
                    _ => g * rng.gen_range(0.5..1.5),
                })
                .collect();
            let ev = prob.evaluate(&k).unwrap();
            let mut theirs = prob.poles(&k);
            for (re, im) in &ev.poles {
                let z = Complex::new(*re, *im);
                let (w, d) = take_nearest(&mut theirs, z);
                // Clustered poles move with rounding by its root, so the bound is loose.
                assert!(d < 1e-5 * (1.0 + z.norm()), "{k:?}: pole {z} vs {w}");
            }
            let (e, h) = prob.loop_perturbation();
            let rc =
                evoloop::robust::stability_radius::stability_radius(&prob.closed_loop(&k), e, h)
                    .unwrap();
            if rc > 0.0 {
                stable += 1;
                assert!(
                    (ev.stability_radius - rc).abs() <= 1e-8 * rc,
                    "{k:?}: r_c {} in the basis, {rc} without",
                    ev.stability_radius
                );
            } else {
                assert_eq!(ev.stability_radius, 0.0, "{k:?}");
            }
            assert_eq!(
                ev.objective.to_bits(),
                prob.objective(&k).to_bits(),
                "{k:?}"
            );
        }
    }
    assert!(stable > 400, "{stable} stable loops");
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
        let prob = spring_problem(k);
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

/// The eigenvalue of `theirs` nearest to `z`, removed from it (eigenvalues come unordered), and
/// its distance to `z`.
fn take_nearest(theirs: &mut Vec<Complex<f64>>, z: Complex<f64>) -> (Complex<f64>, f64) {
    let (i, d) = theirs
        .iter()
        .enumerate()
        .map(|(i, w)| (i, (w - z).norm()))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("as many eigenvalues on both sides");
    (theirs.remove(i), d)
}

#[test]
fn the_hqr_eigenvalues_match_the_schur_decomposition() {
    use evoloop::linalg::eigenvalues;
    let mut rng = rand::rngs::StdRng::seed_from_u64(17);
    let key = |z: &Complex<f64>| (z.re, z.im);
    for trial in 0..300 {
        let n = 1 + trial % 12;
        let mut m = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-3.0..3.0));
        // The QR iteration alone on a matrix already in Hessenberg form, every other trial.
        let mut ours = if trial % 2 == 0 {
            eigenvalues(&m).expect("converges")
        } else {
            let mut h = m.clone();
            h.fill_lower_triangle(0.0, 2);
            m = h;
            evoloop::linalg::hessenberg_eigenvalues(&m).expect("converges")
        };
        let mut theirs: Vec<Complex<f64>> = m.complex_eigenvalues().iter().copied().collect();
        assert_eq!(ours.len(), n);
        // Match each of ours to the nearest of theirs (eigenvalues are unordered).
        for z in ours.drain(..) {
            let (_, d) = take_nearest(&mut theirs, z);
            assert!(
                d < 1e-7 * (1.0 + z.norm()),
                "n = {n}: {:?} has no match",
                key(&z)
            );
        }
    }
}

#[test]
fn the_square_reduced_hamiltonian_eigenvalues_match_the_schur_decomposition() {
    // M = [[A, G], [Q, -A']] with G, Q symmetric: its eigenvalues are +-lambda; the square-reduced
    // method gives one of each pair, which must be, up to sign, one of nalgebra's, and together
    // with their negatives all of them. Its accuracy is about eps |M|^2 / |lambda|.
    use evoloop::linalg::hamiltonian_eigenvalues;
    let mut rng = rand::rngs::StdRng::seed_from_u64(29);
    let mut on_axis = 0;
    for trial in 0..400 {
        let n = 1 + trial % 7;
        let a = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-3.0..3.0));
        let g = DMatrix::from_fn(n, n, |_, _| rng.gen_range(0.0..1.0));
        let q = DMatrix::from_fn(n, n, |_, _| rng.gen_range(0.0..1.0));
        // Semidefinite G and -Q (as the norm's are) leave imaginary eigenvalues in some trials.
        let (g, q) = (&g * g.transpose(), -(&q * q.transpose()));
        let mut m = DMatrix::zeros(2 * n, 2 * n);
        m.view_mut((0, 0), (n, n)).copy_from(&a);
        m.view_mut((0, n), (n, n)).copy_from(&g);
        m.view_mut((n, 0), (n, n)).copy_from(&q);
        m.view_mut((n, n), (n, n)).copy_from(&(-a.transpose()));
        let half = hamiltonian_eigenvalues(&m).expect("converges");
        assert_eq!(half.len(), n);
        let mut theirs: Vec<Complex<f64>> = m.complex_eigenvalues().iter().copied().collect();
        let scale = m.norm().powi(2);
        for z in half.iter().flat_map(|z| [*z, -*z]) {
            let (w, d) = take_nearest(&mut theirs, z);
            assert!(
                d < 1e-9 * scale / z.norm().max(1e-3),
                "n = {n}: {z} has no match ({w})"
            );
        }
        on_axis += half.iter().filter(|z| z.re == 0.0).count();
    }
    assert!(on_axis > 50, "{on_axis} imaginary pairs");
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

// ------------------------------------------------ the loop with the Kalman filter (issue 64)

/// The default scenario's filter: process noise 1, its sensor's noise 0.0005 and resolution
/// 0.0001, run at 1 kHz.
fn filtered(prob: RobustProblem) -> RobustProblem {
    let design = evoloop::law::estimator::KalmanDesign {
        process_noise: 1.0,
        measurement_noise: (0.0005f64.powi(2) + 0.0001f64.powi(2) / 12.0).sqrt(),
        state_noise: 0.0,
    };
    prob.with_observer(design, 0.001).unwrap()
}

/// The default scenario's gains (the paper's DEFC row of Table 9).
const DEFC: [f64; 5] = [18.49, 19.04, 47.27, 7.30, -10.54];

/// The loop's r_c by the Hamiltonian algorithm equals a dense sweep's, and a perturbation of
/// exactly that norm, built from G(jw)'s singular vectors at the peak, puts an eigenvalue of the
/// loop on the imaginary axis: r_c is attained, not only bounded.
#[test]
fn the_loop_with_the_filter_has_an_rc_a_perturbation_of_that_norm_attains() {
    let prob = filtered(RobustProblem::paper());
    let a = prob.whole_loop(&DEFC, None);
    assert_eq!(a.nrows(), 9, "[x; xi; x_hat]");
    let (e, h) = prob.loop_perturbation();
    let (norm, w) = hinf_norm(&a, e, h).unwrap();
    let sweep = hinf_norm_sweep(&a, e, h, 4000);
    assert!(
        (norm - sweep).abs() <= 1e-6 * norm,
        "{norm} vs sweep {sweep}"
    );
    let rc = prob.evaluate(&DEFC).unwrap().stability_radius;
    assert!((rc - 1.0 / norm).abs() <= 1e-12 * rc);

    let c = |m: &DMatrix<f64>| m.map(|v| Complex::new(v, 0.0));
    let jw = Complex::new(0.0, w);
    let n = a.nrows();
    let resolvent = (DMatrix::<Complex<f64>>::identity(n, n) * jw - c(&a))
        .try_inverse()
        .unwrap();
    let g = c(h) * &resolvent * c(e);
    let svd = g.clone().svd(true, true);
    let i = svd.singular_values.imax();
    let s = svd.singular_values[i];
    assert!(
        (s - norm).abs() <= 1e-6 * norm,
        "peak at w = {w}: {s} vs {norm}"
    );
    let u = svd.u.unwrap().column(i).into_owned();
    let v = svd.v_t.unwrap().row(i).adjoint();
    let delta = &v * u.adjoint() / Complex::new(s, 0.0);
    assert!((delta.norm() - rc).abs() <= 1e-6 * rc, "||delta|| = r_c");
    let perturbed = c(&a) + c(e) * delta * c(h);
    let gap = (DMatrix::<Complex<f64>>::identity(n, n) * jw - perturbed)
        .svd(false, false)
        .singular_values
        .min();
    assert!(gap <= 1e-8 * (1.0 + w), "jw = {w}j is an eigenvalue: {gap}");
}

/// Separation: on the nominal plant the loop's poles are the state feedback's and the filter's.
#[test]
fn the_loop_with_the_filter_has_the_feedback_and_the_filter_poles() {
    let prob = filtered(RobustProblem::paper());
    let mut whole: Vec<Complex<f64>> = evoloop::linalg::eig(&prob.whole_loop(&DEFC, None));
    let mut parts: Vec<Complex<f64>> = prob.poles(&DEFC);
    let o = prob.observer.as_ref().unwrap();
    parts.extend(o.error_poles(&prob.nominal_model()));
    let key = |p: &Complex<f64>| {
        (p.re * 1e6).round() as i64 * 1_000_000_000 + (p.im * 1e3).round() as i64
    };
    whole.sort_by_key(key);
    parts.sort_by_key(key);
    assert_eq!(whole.len(), parts.len());
    for (a, b) in whole.iter().zip(&parts) {
        assert!((a - b).norm() <= 1e-6 * (1.0 + b.norm()), "{a} vs {b}");
    }
}

/// The sampled loop's matrix is the controller as it runs: the law with its Kalman filter,
/// stepped against the plant held over each period (another spring than the filter's model),
/// gives the same outputs and commands as powers of the matrix.
#[test]
fn the_sampled_loop_matrix_is_the_controller_as_it_runs() {
    use evoloop::law::Controller;
    use evoloop::law::StateFeedback;
    let prob = filtered(RobustProblem::paper());
    let o = prob.observer.as_ref().unwrap();
    let plant = evoloop::plant::two_mass::TwoMass::new(1.0, 1.0, 1.3, Sensor::Far).linear_model();
    let m = evoloop::robust::observer::sampled_loop(&plant, &o.filter, o.period, &DEFC).unwrap();
    let sampled = plant.at_period(o.period).unwrap();
    let mut law = StateFeedback::new(&DEFC, o.period, None).with_kalman(&o.filter, 0);
    let mut x = [0.3, -0.2, 0.1, 0.4];
    let mut z = DVector::from_vec(vec![0.3, -0.2, 0.1, 0.4, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let mut state = evoloop::msg::PlantState {
        n_x: 4,
        ..Default::default()
    };
    let sp = evoloop::reference::Setpoint::default();
    let mut u = [0.0];
    for k in 0..2000u64 {
        state.seq = k;
        state.y[0] = (0..4).map(|j| sampled.c(j) * x[j]).sum();
        law.step(&state, &sp, &mut u);
        state.u_applied[0] = u[0];
        // The plant's next state under the law's command, beside the matrix's.
        let next = &m * &z;
        let x_next: Vec<f64> = (0..4)
            .map(|i| (0..4).map(|j| sampled.a(i, j) * x[j]).sum::<f64>() + sampled.b(i) * u[0])
            .collect();
        for i in 0..4 {
            assert!(
                (next[i] - x_next[i]).abs() <= 1e-9 * (1.0 + x_next[i].abs()),
                "sample {k}, state {i}: matrix {} vs law {}",
                next[i],
                x_next[i]
            );
        }
        x.copy_from_slice(&x_next);
        z = next;
    }
}

/// What r_c promises holds where the controller runs: the sampled loop with its filter stays
/// stable for every spring within r_c / 2 of the nominal one (a spring change is a perturbation
/// of norm 2|dk|), and so does the continuous loop r_c is computed on.
#[test]
fn the_sampled_loop_is_stable_over_the_springs_rc_guarantees() {
    for prob in [
        filtered(RobustProblem::paper()),
        filtered(spring_problem(1.0)),
    ] {
        let rc = prob.evaluate(&DEFC).unwrap().stability_radius;
        assert!(rc > 0.0, "the loop with the filter is stable");
        let r = prob.spring_ranges(&DEFC, rc);
        let (lo, hi) = r.guaranteed.unwrap();
        for (name, (l, h)) in [
            ("continuous", r.continuous),
            ("sampled", r.sampled.unwrap()),
        ] {
            assert!(
                l.is_none_or(|l| l <= lo),
                "{name}: unstable at {l:?} > {lo}"
            );
            assert!(
                h.is_none_or(|h| h >= hi),
                "{name}: unstable at {h:?} < {hi}"
            );
        }
    }
}

/// The command's noise the analysis predicts from the sampled loop's stationary covariance is
/// what the law with its filter gives on a seeded noisy sensor (a Monte Carlo run of 200 000
/// samples, the statistical error a few per cent).
#[test]
fn the_command_noise_of_the_loop_with_the_filter_is_what_a_noisy_run_gives() {
    use evoloop::law::{Controller, StateFeedback};
    let prob = filtered(RobustProblem::paper());
    let o = prob.observer.as_ref().unwrap();
    let plant = prob.nominal_model();
    let sigma = o.design.measurement_noise;
    let predicted =
        evoloop::robust::observer::command_noise(&plant, &o.filter, o.period, &DEFC, sigma)
            .unwrap();
    let sampled = plant.at_period(o.period).unwrap();
    let mut law = StateFeedback::new(&DEFC, o.period, None).with_kalman(&o.filter, 0);
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut gauss = move || {
        let (u1, u2): (f64, f64) = (rng.gen::<f64>().max(1e-300), rng.gen());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let mut x = [0.0; 4];
    let mut state = evoloop::msg::PlantState {
        n_x: 4,
        ..Default::default()
    };
    let sp = evoloop::reference::Setpoint::default();
    let mut u = [0.0];
    let (mut sum, mut sum2, mut count) = (0.0, 0.0, 0.0);
    for k in 0..220_000u64 {
        state.seq = k;
        state.y[0] = (0..4).map(|j| sampled.c(j) * x[j]).sum::<f64>() + sigma * gauss();
        law.step(&state, &sp, &mut u);
        state.u_applied[0] = u[0];
        if k >= 20_000 {
            (sum, sum2, count) = (sum + u[0], sum2 + u[0] * u[0], count + 1.0);
        }
        let next: Vec<f64> = (0..4)
            .map(|i| (0..4).map(|j| sampled.a(i, j) * x[j]).sum::<f64>() + sampled.b(i) * u[0])
            .collect();
        x.copy_from_slice(&next);
    }
    let measured = (sum2 / count - (sum / count).powi(2)).sqrt();
    assert!(
        (measured - predicted).abs() <= 0.05 * predicted,
        "measured {measured} against predicted {predicted}"
    );
}
