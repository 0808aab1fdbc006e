//! evoloop's rigid-body dynamics as a plain library: load a URDF, then the joint-space inertia
//! matrix (CRBA), inverse dynamics (RNEA) and forward dynamics (Cholesky of M), each checked
//! against another: M is symmetric positive definite, forward dynamics inverts RNEA, and RNEA at
//! rest is the gravity torque.
//!
//!     cargo run --release --example dynamics_library [URDF]   # default: config/robots/arm7.urdf

use std::path::Path;

/// What the checks measured on `robot` at a fixed state.
#[derive(Debug)]
pub struct Checks {
    /// The robot's joint count.
    pub joints: usize,
    /// max |M - M^T|.
    pub asymmetry: f64,
    /// Whether M's Cholesky factorisation exists (M positive definite).
    pub positive_definite: bool,
    /// max |qdd - forward_dynamics(rnea(q, qd, qdd))|.
    pub round_trip: f64,
    /// max |rnea(q, 0, 0) - gravity_torque(q)|.
    pub gravity: f64,
}

/// Load the URDF at `robot` and run the three checks at one fixed (q, qd, qdd). Fails when the
/// file does not load or M is not positive definite there.
pub fn run(robot: &Path) -> Result<Checks, String> {
    let model = evoloop::dynamics::load(robot).map_err(|e| e.to_string())?;
    let n = model.dof();
    let mut data = model.data();
    let q: Vec<f64> = (0..n).map(|j| 0.3 - 0.1 * j as f64).collect();
    let qd: Vec<f64> = (0..n).map(|j| 0.5 * (j as f64).sin()).collect();
    let qdd: Vec<f64> = (0..n).map(|j| 1.0 - 0.2 * j as f64).collect();
    let m = model.mass_matrix(&mut data, &q).clone();
    let asymmetry = (&m - m.transpose()).amax();
    let positive_definite = m.clone().cholesky().is_some();
    let mut tau = vec![0.0; n];
    // Inverse dynamics with the joints' friction (forward dynamics takes it off again).
    model.inverse_dynamics(&mut data, &q, &qd, &qdd, &mut tau);
    let mut back = vec![0.0; n];
    model
        .forward_dynamics(&mut data, &q, &qd, &tau, &mut back)
        .map_err(|_| "M is not positive definite".to_string())?;
    let round_trip = back
        .iter()
        .zip(&qdd)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let zero = vec![0.0; n];
    model.rnea(&mut data, &q, &zero, &zero, &mut tau);
    let mut g = vec![0.0; n];
    model.gravity_torque(&mut data, &q, &mut g);
    let gravity = tau
        .iter()
        .zip(&g)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    Ok(Checks {
        joints: n,
        asymmetry,
        positive_definite,
        round_trip,
        gravity,
    })
}

#[allow(dead_code)]
fn main() {
    let robot = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "config/robots/arm7.urdf".into());
    match run(Path::new(&robot)) {
        Ok(c) => println!(
            "{robot}: {} joints; |M - M^T| {:.1e}, M positive definite: {}, forward(inverse) \
             round trip {:.1e} rad/s^2, RNEA at rest vs gravity {:.1e} N m",
            c.joints, c.asymmetry, c.positive_definite, c.round_trip, c.gravity
        ),
        Err(e) => {
            eprintln!("{robot}: {e}");
            std::process::exit(2);
        }
    }
}
