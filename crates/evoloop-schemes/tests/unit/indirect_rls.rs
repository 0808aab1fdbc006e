use evoloop_schemes::indirect::rls::{InformationRls, Rls};

#[test]
fn converges_to_the_true_slope_and_follows_a_change() {
    let mut r = Rls::new(0.0, 0.99);
    let x = |k: usize| 1.0 + (k as f64 * 0.37).sin();
    for k in 0..1000 {
        r.update(2.0 * x(k), x(k));
    }
    assert!((r.theta - 2.0).abs() < 1e-9, "{}", r.theta);
    // After a change the old data fade as lambda^n: 0.99^1000 ~ 4e-5.
    for k in 1000..2000 {
        r.update(3.0 * x(k), x(k));
    }
    assert!((r.theta - 3.0).abs() < 1e-3, "{}", r.theta);
    assert_eq!(r.updates, 2000);
}

/// Noisy data with pauses in the excitation: the information forgetting neither winds up
/// in the pauses nor stays on the old value after a change, and its reported deviation
/// covers the error.
#[test]
fn information_forgetting_follows_a_change_across_pauses() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut r = InformationRls::new(1.0, 0.005, 1e5);
    // Uniform noise of standard deviation 0.1.
    let mut noise = || 0.1 * (rng.gen::<f64>() - 0.5) * 12f64.sqrt();
    // Excitation for 500 samples, rest (x = 1e-4) for 5000, three times; the slope 2 -> 3.
    for (slope, phase) in [(2.0, 0), (2.0, 1), (3.0, 2), (3.0, 3)] {
        for k in 0..5500 {
            let x = if k < 500 {
                1.0 + (k as f64 * 0.37).sin()
            } else {
                1e-4
            };
            r.update(slope * x + noise(), x, 0.01);
        }
        let err = (r.theta - slope).abs();
        assert!(
            err <= 3.0 * r.std(),
            "phase {phase}: theta {} std {}",
            r.theta,
            r.std()
        );
        assert!(r.std() / slope < 0.01, "phase {phase}: std {}", r.std());
    }
}
