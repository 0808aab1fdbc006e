//! The population methods allocate nothing per generation: a counting global allocator watches
//! ask and tell of every algorithm of the study (and DE with its diversity window) once each has
//! run a few generations. Its own test binary, so no other test allocates while it counts.

use evoloop::optim::by_name::{build, ALGORITHMS};
use evoloop::optim::{DeConfig, DifferentialEvolution, Optimiser};
use std::sync::atomic::Ordering;

use evoloop::rt::alloc_count::{self as counting_alloc, COUNT};

#[global_allocator]
static A: counting_alloc::Counting = counting_alloc::Counting;

/// Generations of ask, evaluate (a 10-D Rastrigin into a preallocated buffer) and tell.
fn generations(opt: &mut dyn Optimiser, n: usize, values: &mut Vec<f64>) {
    for _ in 0..n {
        let asked = opt.ask();
        values.clear();
        values.extend(asked.iter().map(|x| {
            x.iter()
                .map(|v| v * v - 10.0 * (std::f64::consts::TAU * v).cos() + 10.0)
                .sum::<f64>()
        }));
        opt.tell(values);
    }
}

#[test]
fn no_population_method_allocates_per_generation() {
    let (lower, upper) = (vec![-5.12; 10], vec![5.12; 10]);
    let mut opts: Vec<(String, Box<dyn Optimiser>)> = ALGORITHMS
        .iter()
        .map(|name| {
            let o: Box<dyn Optimiser> = build(name, &lower, &upper, 20, 20_000, 1).unwrap();
            (name.to_string(), o)
        })
        .collect();
    let de = DifferentialEvolution::new(DeConfig {
        np: 20,
        f: 0.5,
        cr: 0.9,
        lower: lower.clone(),
        upper: upper.clone(),
        seed: 1,
        diversity_stop: true,
        eta: 5,
        epsilon: 1e-12,
    })
    .unwrap();
    opts.push(("de with its diversity window".into(), Box::new(de)));
    let mut values = Vec::with_capacity(64);
    for (name, opt) in &mut opts {
        // Warm-up: the first generations fill scratch buffers, DE's window and the GA's children.
        generations(opt.as_mut(), 10, &mut values);
        COUNT.store(0, Ordering::SeqCst);
        counting_alloc::arm();
        generations(opt.as_mut(), 200, &mut values);
        counting_alloc::disarm();
        let n = COUNT.load(Ordering::SeqCst);
        assert_eq!(n, 0, "{name}: {n} allocations in 200 generations");
        assert!(opt.best().1.is_finite());
    }
}
