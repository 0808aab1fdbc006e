//! Rigid-body dynamics against independent references: the properties of eq. 1 (M symmetric
//! positive definite, skew symmetry of Mdot - 2C, energy conservation), inverse ∘ forward = id,
//! a hand-derived planar 2-link arm, D-H = URDF for one arm, and clear errors for bad files.

use evoloop::dynamics::{self, Model};
use evoloop::plant::{Arm, PlantSim};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};

fn robot(name: &str) -> Model {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("config/robots")
        .join(name);
    dynamics::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

fn random_state(rng: &mut ChaCha8Rng, n: usize, scale: f64) -> Vec<f64> {
    (0..n).map(|_| rng.gen_range(-scale..scale)).collect()
}

/// A robot file written in the style of a ROS description package (`tests/robots/`).
fn ros_style(name: &str) -> Model {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/robots")
        .join(name);
    dynamics::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

/// The arms under test: the two shipped D-H robots, the URDF arm, a branched URDF tree, and three
/// files as ROS packages ship them (UR-style with transmissions and gazebo tags, Panda-style with
/// full inertia tensors and joint friction, iiwa-style with a massless base).
fn arms() -> Vec<Model> {
    vec![
        robot("arm3.toml"),
        robot("industrial6.toml"),
        robot("arm3.urdf"),
        ros_style("branched.urdf"),
        ros_style("ur5_style.urdf"),
        ros_style("panda_style.urdf"),
        ros_style("iiwa_style.urdf"),
    ]
}

#[test]
fn mass_matrix_is_symmetric_positive_definite() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for m in arms() {
        let n = m.dof();
        let mut d = m.data();
        for _ in 0..200 {
            let q = random_state(&mut rng, n, 3.0);
            let mm = m.mass_matrix(&mut d, &q).clone();
            assert!(
                (&mm - mm.transpose()).amax() < 1e-12,
                "{}: M not symmetric",
                m.name
            );
            let eig = mm.clone().symmetric_eigen().eigenvalues;
            assert!(eig.min() > 0.0, "{}: M not PD at {q:?}: {eig}", m.name);
            // Kinetic energy from M equals the sum over bodies (RNEA-free check of CRBA):
            // qdᵀ M qd = qdᵀ (ID(q, qd, 0) - ID(q, 0, 0)) is not it; use M's columns = ID(e_j)
            // without gravity and velocity instead.
            for j in 0..n {
                let mut e = vec![0.0; n];
                e[j] = 1.0;
                let mut tau = vec![0.0; n];
                let mut g = vec![0.0; n];
                m.rnea(&mut d, &q, &vec![0.0; n], &e, &mut tau);
                m.gravity_torque(&mut d, &q, &mut g);
                for i in 0..n {
                    let col = tau[i] - g[i];
                    assert!(
                        (col - mm[(i, j)]).abs() < 1e-10 * (1.0 + mm[(i, j)].abs()),
                        "{}: CRBA != RNEA column",
                        m.name
                    );
                }
            }
        }
    }
}

#[test]
fn coriolis_matrix_makes_mdot_minus_2c_skew_symmetric() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for m in arms() {
        let n = m.dof();
        let mut d = m.data();
        for _ in 0..50 {
            let q = random_state(&mut rng, n, 2.5);
            let qd = random_state(&mut rng, n, 2.0);
            let mut c = DMatrix::zeros(n, n);
            m.coriolis_matrix(&mut d, &q, &qd, &mut c);
            // V = C qd.
            let mut v = vec![0.0; n];
            m.coriolis(&mut d, &q, &qd, &mut v);
            let cqd = &c * nalgebra::DVector::from_column_slice(&qd);
            for i in 0..n {
                assert!(
                    (cqd[i] - v[i]).abs() < 1e-10 * (1.0 + v[i].abs()),
                    "{}: V != C qd",
                    m.name
                );
            }
            // Mdot along qd by central differences.
            let h = 1e-6;
            let qp: Vec<f64> = q.iter().zip(&qd).map(|(a, b)| a + h * b).collect();
            let qm: Vec<f64> = q.iter().zip(&qd).map(|(a, b)| a - h * b).collect();
            let mp = m.mass_matrix(&mut d, &qp).clone();
            let mm = m.mass_matrix(&mut d, &qm).clone();
            let mdot = (mp - mm) / (2.0 * h);
            let s = &mdot - &c * 2.0;
            let scale = 1.0 + mdot.amax();
            // Skew: S + Sᵀ = 0, i.e. yᵀ S y = 0 for every y (eq. 3).
            assert!(
                (&s + s.transpose()).amax() < 1e-6 * scale,
                "{}: Mdot - 2C not skew: {}",
                m.name,
                (&s + s.transpose()).amax()
            );
            let y = nalgebra::DVector::from_vec(random_state(&mut rng, n, 1.0));
            assert!((y.transpose() * &s * &y)[0].abs() < 1e-6 * scale);
        }
    }
}

#[test]
fn inverse_dynamics_inverts_forward_dynamics() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for m in arms() {
        let n = m.dof();
        let mut d = m.data();
        for _ in 0..500 {
            let q = random_state(&mut rng, n, 3.0);
            let qd = random_state(&mut rng, n, 3.0);
            let tau = random_state(&mut rng, n, 50.0);
            // Both routes: CRBA + Cholesky and ABA.
            for aba in [false, true] {
                let mut qdd = vec![0.0; n];
                if aba {
                    m.forward_dynamics_aba(&mut d, &q, &qd, &tau, &mut qdd)
                } else {
                    m.forward_dynamics(&mut d, &q, &qd, &tau, &mut qdd)
                }
                .unwrap();
                let mut back = vec![0.0; n];
                m.inverse_dynamics(&mut d, &q, &qd, &qdd, &mut back);
                let scale = tau.iter().chain(&back).fold(1.0f64, |a, b| a.max(b.abs()));
                for i in 0..n {
                    assert!(
                        (back[i] - tau[i]).abs() <= 1e-10 * scale,
                        "{} (aba: {aba}): tau {} -> {}",
                        m.name,
                        tau[i],
                        back[i]
                    );
                }
            }
        }
    }
}

/// Featherstone's articulated-body algorithm against the CRBA + Cholesky solve on every test arm
/// (revolute and prismatic joints, a branched tree, friction, armature, a massless base), at
/// random states: equal to 1e-12 of the accelerations' scale (inverse dynamics inverts both:
/// `inverse_dynamics_inverts_forward_dynamics`).
#[test]
fn aba_equals_the_crba_cholesky_solve() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for m in arms() {
        let n = m.dof();
        let mut d = m.data();
        let mut worst: f64 = 0.0;
        for _ in 0..500 {
            let q = random_state(&mut rng, n, 3.0);
            let qd = random_state(&mut rng, n, 3.0);
            let tau = random_state(&mut rng, n, 50.0);
            let (mut crba, mut aba) = (vec![0.0; n], vec![0.0; n]);
            m.forward_dynamics(&mut d, &q, &qd, &tau, &mut crba)
                .unwrap();
            m.forward_dynamics_aba(&mut d, &q, &qd, &tau, &mut aba)
                .unwrap();
            let scale = crba.iter().fold(1.0f64, |a, b| a.max(b.abs()));
            for i in 0..n {
                worst = worst.max((aba[i] - crba[i]).abs() / scale);
            }
        }
        assert!(
            worst <= 1e-12,
            "{}: ABA vs CRBA, relative {worst:e}",
            m.name
        );
    }
}

/// Total energy of a torque-free, friction-free arm over 10 s of RK4, at two step sizes.
fn energy_drift(m: &Model, h: f64) -> f64 {
    let n = m.dof();
    let mut sim = PlantSim::new(Box::new(Arm::new(m.clone(), &vec![0.4; n])), h, 0.0, 0);
    for i in 0..n {
        sim.x[n + i] = 1.0 - 0.3 * i as f64;
    }
    let mut d = m.data();
    let energy = |x: &[f64], d: &mut dynamics::Data| {
        m.kinetic_energy(d, &x[..n], &x[n..]) + m.potential_energy(d, &x[..n])
    };
    let e0 = energy(&sim.x, &mut d);
    let u = vec![0.0; n];
    let mut worst: f64 = 0.0;
    for _ in 0..1000 {
        sim.advance(&u, 0.01);
        worst = worst.max((energy(&sim.x, &mut d) - e0).abs());
    }
    worst / e0.abs().max(1.0)
}

fn conservative(mut m: Model) -> Model {
    for b in &mut m.bodies {
        b.friction = Default::default();
        b.friction.v_smooth = 0.01;
        b.limits.q_min = f64::NEG_INFINITY;
        b.limits.q_max = f64::INFINITY;
        b.limits.effort = f64::INFINITY;
    }
    m
}

#[test]
fn energy_is_conserved_without_torque_and_friction() {
    for m in [
        robot("arm3.toml"),
        robot("industrial6.toml"),
        ros_style("ur5_style.urdf"),
        ros_style("panda_style.urdf"),
        ros_style("iiwa_style.urdf"),
    ] {
        let m = conservative(m);
        let coarse = energy_drift(&m, 2e-3);
        let fine = energy_drift(&m, 1e-3);
        eprintln!("{}: drift {coarse:e} (2 ms) {fine:e} (1 ms)", m.name);
        assert!(
            coarse < 1e-4,
            "{}: relative energy drift {coarse:e} at h = 2 ms",
            m.name
        );
        // RK4: halving the step shrinks the drift (by ~2^4 ideally).
        assert!(
            fine < coarse / 4.0,
            "{}: drift {fine:e} at 1 ms vs {coarse:e} at 2 ms",
            m.name
        );
    }
}

#[test]
fn planar_two_link_matches_closed_form() {
    // Planar arm in the x-y plane, gravity along -y, links of length l, com at lc, mass m,
    // inertia about the com I (about z). Both D-H conventions describe it.
    let (l1, l2, lc1, lc2, m1, m2, i1, i2, g) = (0.5, 0.4, 0.2, 0.15, 2.0, 1.5, 0.05, 0.03, 9.81);
    let row = |a: f64, com: f64, mass: f64, izz: f64| {
        format!("[[joint]]\na = {a}\nalpha = 0.0\nd = 0.0\nmass = {mass}\ncom = [{com}, 0.0, 0.0]\ninertia = [0.001, {izz}, {izz}, 0.0, 0.0, 0.0]\n")
    };
    let standard = format!(
        "convention = \"standard\"\ngravity = [0.0, -{g}, 0.0]\n{}{}",
        row(l1, lc1 - l1, m1, i1),
        row(l2, lc2 - l2, m2, i2)
    );
    let modified = format!(
        "convention = \"modified\"\ngravity = [0.0, -{g}, 0.0]\n{}{}",
        row(0.0, lc1, m1, i1),
        row(l1, lc2, m2, i2)
    );
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for text in [standard, modified] {
        let m = dynamics::dh::parse(&text, Path::new("planar.toml")).unwrap();
        let mut d = m.data();
        for _ in 0..100 {
            let q = random_state(&mut rng, 2, 3.0);
            let qd = random_state(&mut rng, 2, 3.0);
            let qdd = random_state(&mut rng, 2, 5.0);
            let (c2, s2) = (q[1].cos(), q[1].sin());
            let (c1, c12) = (q[0].cos(), (q[0] + q[1]).cos());
            let m11 = i1 + i2 + m1 * lc1 * lc1 + m2 * (l1 * l1 + lc2 * lc2 + 2.0 * l1 * lc2 * c2);
            let m12 = i2 + m2 * (lc2 * lc2 + l1 * lc2 * c2);
            let m22 = i2 + m2 * lc2 * lc2;
            let h = m2 * l1 * lc2 * s2;
            let v = [
                -h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]),
                h * qd[0] * qd[0],
            ];
            let gv = [
                (m1 * lc1 + m2 * l1) * g * c1 + m2 * lc2 * g * c12,
                m2 * lc2 * g * c12,
            ];
            let tau_ref = [
                m11 * qdd[0] + m12 * qdd[1] + v[0] + gv[0],
                m12 * qdd[0] + m22 * qdd[1] + v[1] + gv[1],
            ];
            let mut tau = [0.0; 2];
            m.inverse_dynamics(&mut d, &q, &qd, &qdd, &mut tau);
            let mm = m.mass_matrix(&mut d, &q).clone();
            let mut gg = [0.0; 2];
            m.gravity_torque(&mut d, &q, &mut gg);
            let mut vv = [0.0; 2];
            m.coriolis(&mut d, &q, &qd, &mut vv);
            for i in 0..2 {
                assert!(
                    (tau[i] - tau_ref[i]).abs() < 1e-12 * (1.0 + tau_ref[i].abs()),
                    "tau {i}"
                );
                assert!((gg[i] - gv[i]).abs() < 1e-12 * (1.0 + gv[i].abs()), "G {i}");
                assert!((vv[i] - v[i]).abs() < 1e-12 * (1.0 + v[i].abs()), "V {i}");
            }
            for (a, b) in [
                (mm[(0, 0)], m11),
                (mm[(0, 1)], m12),
                (mm[(1, 0)], m12),
                (mm[(1, 1)], m22),
            ] {
                assert!((a - b).abs() < 1e-12, "M {a} vs {b}");
            }
        }
    }
}

#[test]
fn dh_and_urdf_descriptions_of_one_arm_agree() {
    let dh = robot("arm3.toml");
    let urdf = robot("arm3.urdf");
    assert_eq!(dh.dof(), urdf.dof());
    let names: Vec<&str> = urdf.bodies.iter().map(|b| b.joint.as_str()).collect();
    assert_eq!(
        names,
        ["waist", "shoulder", "elbow"],
        "URDF joints in chain order"
    );
    let (mut d1, mut d2) = (dh.data(), urdf.data());
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..200 {
        let q = random_state(&mut rng, 3, 2.5);
        let qd = random_state(&mut rng, 3, 2.0);
        let qdd = random_state(&mut rng, 3, 5.0);
        let (mut t1, mut t2) = ([0.0; 3], [0.0; 3]);
        dh.inverse_dynamics(&mut d1, &q, &qd, &qdd, &mut t1);
        urdf.inverse_dynamics(&mut d2, &q, &qd, &qdd, &mut t2);
        for i in 0..3 {
            assert!(
                (t1[i] - t2[i]).abs() < 1e-12 * (1.0 + t1[i].abs()),
                "tau[{i}] {} vs {}",
                t1[i],
                t2[i]
            );
        }
        let m1 = dh.mass_matrix(&mut d1, &q).clone();
        let m2 = urdf.mass_matrix(&mut d2, &q).clone();
        assert!((m1 - m2).amax() < 1e-12);
        let (mut a1, mut a2) = ([0.0; 3], [0.0; 3]);
        dh.forward_dynamics(&mut d1, &q, &qd, &t1, &mut a1).unwrap();
        urdf.forward_dynamics(&mut d2, &q, &qd, &t1, &mut a2)
            .unwrap();
        for i in 0..3 {
            assert!((a1[i] - a2[i]).abs() < 1e-9 * (1.0 + a1[i].abs()));
        }
    }
}

#[test]
fn fixed_joints_merge_inertia_into_the_moving_body() {
    // One link of 2 kg split into two 1 kg halves joined by a fixed joint (with a rotated
    // origin) has the dynamics of the unsplit link.
    let whole = r#"<robot name="w">
      <link name="base"/>
      <link name="l1"><inertial><origin xyz="0.25 0 0"/><mass value="2"/>
        <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.0427" iyz="0" izz="0.0427"/></inertial></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 1 0"/>
        <limit lower="-3" upper="3" effort="100" velocity="5"/></joint>
    </robot>"#;
    // Halves: rods of 0.25 m at x = 0.125 and 0.375; about each half's com: iyy = m L^2/12 + ...
    // Each half as a rod of 1 kg, length 0.25, same section: iyy_c = 1*(0.0625)/12 + 0.001 = 0.00620833.
    // Whole about its com: 2*(0.25)/12 + 0.002 = 0.0436667 -> use that for the whole instead.
    let whole = whole.replace("0.0427", "0.043666666666666666");
    let split = r#"<robot name="s">
      <link name="base"/>
      <link name="a"><inertial><origin xyz="0.125 0 0"/><mass value="1"/>
        <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.006208333333333333" iyz="0" izz="0.006208333333333333"/></inertial></link>
      <link name="b"><inertial><origin xyz="0 0 -0.125" rpy="0 1.5707963267948966 0"/><mass value="1"/>
        <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.006208333333333333" iyz="0" izz="0.006208333333333333"/></inertial></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 1 0"/>
        <limit lower="-3" upper="3" effort="100" velocity="5"/></joint>
      <joint name="weld" type="fixed"><parent link="a"/><child link="b"/>
        <origin xyz="0.25 0 0" rpy="0 -1.5707963267948966 0"/></joint>
    </robot>"#;
    let w = dynamics::urdf::parse(&whole, Path::new("whole.urdf")).unwrap();
    let s = dynamics::urdf::parse(split, Path::new("split.urdf")).unwrap();
    assert_eq!(s.dof(), 1);
    let (mut dw, mut ds) = (w.data(), s.data());
    for q in [-1.0, 0.0, 0.7] {
        let (mut a, mut b) = ([0.0], [0.0]);
        w.inverse_dynamics(&mut dw, &[q], &[0.5], &[1.5], &mut a);
        s.inverse_dynamics(&mut ds, &[q], &[0.5], &[1.5], &mut b);
        assert!((a[0] - b[0]).abs() < 1e-12, "{} vs {}", a[0], b[0]);
    }
}

#[test]
fn branched_tree_orders_depth_first_and_decouples_branches() {
    let m = ros_style("branched.urdf");
    let names: Vec<&str> = m.bodies.iter().map(|b| b.joint.as_str()).collect();
    assert_eq!(names, ["l_shoulder", "l_elbow", "r_shoulder", "r_slide"]);
    let mut d = m.data();
    let mm = m.mass_matrix(&mut d, &[0.3, -0.5, 0.2, 0.05]).clone();
    for (i, j) in [(0, 2), (0, 3), (1, 2), (1, 3)] {
        assert_eq!(
            mm[(i, j)],
            0.0,
            "joints on different branches are inertially decoupled"
        );
    }
}

fn load_err(name: &str, text: &str) -> String {
    let p = PathBuf::from(name);
    let r = if name.ends_with(".urdf") {
        dynamics::urdf::parse(text, &p)
    } else {
        dynamics::dh::parse(text, &p)
    };
    r.expect_err("must be rejected").to_string()
}

const TWO_LINKS: &str = r#"<robot name="r">
  <link name="base"/>
  <link name="upper">INERTIAL_UPPER</link>
  <link name="fore">INERTIAL_FORE</link>
  <joint name="shoulder" type="SHOULDER_TYPE"><parent link="base"/><child link="upper"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="50" velocity="5"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="50" velocity="5"/></joint>
  EXTRA
</robot>"#;

const GOOD_INERTIAL: &str = r#"<inertial><origin xyz="0.15 0 0"/><mass value="1"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>"#;

fn two_links(upper: &str, fore: &str, shoulder: &str, extra: &str) -> String {
    TWO_LINKS
        .replace("INERTIAL_UPPER", upper)
        .replace("INERTIAL_FORE", fore)
        .replace("SHOULDER_TYPE", shoulder)
        .replace("EXTRA", extra)
}

#[test]
fn bad_robot_files_name_the_link_or_joint() {
    assert!(dynamics::urdf::parse(
        &two_links(GOOD_INERTIAL, GOOD_INERTIAL, "revolute", ""),
        Path::new("ok.urdf")
    )
    .is_ok());

    let e = load_err(
        "missing.urdf",
        &two_links(GOOD_INERTIAL, "", "revolute", ""),
    );
    assert!(
        e.contains("missing.urdf")
            && e.contains("joint `elbow`")
            && e.contains("link `fore`")
            && e.contains("inertial"),
        "{e}"
    );

    let not_pd = GOOD_INERTIAL.replace(r#"iyy="0.01""#, r#"iyy="-0.01""#);
    let e = load_err(
        "notpd.urdf",
        &two_links(GOOD_INERTIAL, &not_pd, "revolute", ""),
    );
    assert!(
        e.contains("link `fore`") && e.contains("not positive (semi-)definite"),
        "{e}"
    );

    // Physically dubious but simulable: refused only in strict mode (tests/robot_files.rs checks
    // the lenient warning).
    let triangle = GOOD_INERTIAL.replace(r#"ixx="0.001""#, r#"ixx="0.05""#);
    let strict = dynamics::LoadOptions {
        strict: true,
        ..Default::default()
    };
    let e = dynamics::urdf::parse_with(
        &two_links(GOOD_INERTIAL, &triangle, "revolute", ""),
        Path::new("tri.urdf"),
        &strict,
    )
    .expect_err("strict refuses")
    .to_string();
    assert!(
        e.contains("link `fore`") && e.contains("triangle") && e.contains("--strict"),
        "{e}"
    );

    let e = load_err(
        "type.urdf",
        &two_links(GOOD_INERTIAL, GOOD_INERTIAL, "hinge", ""),
    );
    assert!(
        e.contains("joint `shoulder`") && e.contains("unknown joint type `hinge`"),
        "{e}"
    );

    let e = load_err(
        "float.urdf",
        &two_links(GOOD_INERTIAL, GOOD_INERTIAL, "floating", ""),
    );
    assert!(
        e.contains("joint `shoulder`") && e.contains("not supported"),
        "{e}"
    );

    // A joint closing a loop: `fore` gets a second parent.
    let loop_joint = r#"<joint name="closure" type="revolute"><parent link="base"/><child link="fore"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#;
    let e = load_err(
        "loop.urdf",
        &two_links(GOOD_INERTIAL, GOOD_INERTIAL, "revolute", loop_joint),
    );
    assert!(e.contains("link `fore`") && e.contains("loop"), "{e}");

    // A loop with no root at all: base becomes the child of fore.
    let back =
        r#"<joint name="back" type="fixed"><parent link="fore"/><child link="base"/></joint>"#;
    let e = load_err(
        "cycle.urdf",
        &two_links(GOOD_INERTIAL, GOOD_INERTIAL, "revolute", back),
    );
    assert!(e.contains("loop"), "{e}");

    let e = load_err(
        "undefined.urdf",
        &two_links(
            GOOD_INERTIAL,
            GOOD_INERTIAL,
            "revolute",
            r#"<joint name="dangling" type="fixed"><parent link="fore"/><child link="ghost"/></joint>"#,
        ),
    );
    assert!(
        e.contains("joint `dangling`") && e.contains("`ghost`"),
        "{e}"
    );

    // D-H tables.
    let row = "[[joint]]\nname = \"j1\"\na = 0.3\nalpha = 0.0\nd = 0.0\n";
    let e = load_err("nomass.toml", &format!("convention = \"standard\"\n{row}"));
    assert!(e.contains("joint `j1`") && e.contains("mass"), "{e}");
    let e = load_err("kind.toml", &format!("convention = \"standard\"\n{row}type = \"ball\"\nmass = 1.0\ncom = [0.0, 0.0, 0.0]\ninertia = [0.1, 0.1, 0.1, 0.0, 0.0, 0.0]\n"));
    assert!(
        e.contains("joint `j1`") && e.contains("unknown joint type `ball`"),
        "{e}"
    );
    // A negative principal moment: no body has it (a zero one, a thin rod, is accepted).
    let e = load_err("pd.toml", &format!("convention = \"standard\"\n{row}mass = 1.0\ncom = [0.0, 0.0, 0.0]\ninertia = [0.1, 0.1, -0.01, 0.0, 0.0, 0.0]\n"));
    assert!(
        e.contains("joint `j1`") && e.contains("not positive (semi-)definite"),
        "{e}"
    );
    let e = load_err("conv.toml", &format!("convention = \"sideways\"\n{row}"));
    assert!(e.contains("convention"), "{e}");
}

#[test]
fn every_call_is_independent_of_what_ran_before_on_the_same_data() {
    // The algorithms share scratch buffers in `Data`; no result may depend on an earlier call.
    let m = robot("industrial6.toml");
    let q = [0.3, -0.5, 0.8, 0.1, 0.2, 0.3];
    let qd = [0.5, 1.0, -1.0, 1.0, 1.0, 1.0];
    let mut fresh = m.data();
    let mut g_ref = [0.0; 6];
    m.gravity_torque(&mut fresh, &q, &mut g_ref);
    let mut used = m.data();
    let mut qdd = [0.0; 6];
    m.forward_dynamics(&mut used, &q, &qd, &[10.0; 6], &mut qdd)
        .unwrap();
    let mut c = DMatrix::zeros(6, 6);
    m.coriolis_matrix(&mut used, &q, &qd, &mut c);
    let mut g = [0.0; 6];
    m.gravity_torque(&mut used, &q, &mut g);
    assert_eq!(g, g_ref, "G(q) after other calls on the same Data");
}

/// Y pi + armature qdd = RNEA and, with the friction columns, = the full inverse dynamics, to
/// 1e-12 relative, on random states of every arm (serial, branched, D-H, URDF).
#[test]
fn regressor_times_parameters_equals_inverse_dynamics_on_random_states() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for m in arms() {
        let n = m.dof();
        let mut d = m.data();
        for friction in [false, true] {
            let mut y = DMatrix::zeros(n, m.regressor_columns(friction));
            let pi = m.parameters(friction);
            assert_eq!(m.parameter_names(friction).len(), pi.len());
            for _ in 0..50 {
                let q = random_state(&mut rng, n, 3.0);
                let qd = random_state(&mut rng, n, 2.0);
                let qdd = random_state(&mut rng, n, 5.0);
                m.regressor(&mut d, &q, &qd, &qdd, &mut y);
                let mut tau = vec![0.0; n];
                if friction {
                    m.inverse_dynamics(&mut d, &q, &qd, &qdd, &mut tau);
                } else {
                    m.rnea(&mut d, &q, &qd, &qdd, &mut tau);
                }
                let scale = tau.iter().fold(1.0f64, |a, t| a.max(t.abs()));
                for j in 0..n {
                    let ypi: f64 = (0..pi.len()).map(|c| y[(j, c)] * pi[c]).sum();
                    let arm = m.bodies[j].armature * qdd[j];
                    assert!(
                        (ypi + arm - tau[j]).abs() <= 1e-12 * scale,
                        "{} joint {j}: Y pi {ypi} + {arm} vs {}",
                        m.name,
                        tau[j]
                    );
                }
            }
        }
    }
}

/// A joint carries only its own body and those beyond it: row j of Y is zero in the columns of
/// every body that is neither j nor a descendant of j (the other branch of a tree included).
#[test]
fn a_joint_row_of_the_regressor_sees_only_the_bodies_it_carries() {
    let m = ros_style("branched.urdf");
    let n = m.dof();
    let mut d = m.data();
    let mut y = DMatrix::zeros(n, m.regressor_columns(false));
    let x: Vec<f64> = (0..n).map(|i| 0.3 + 0.1 * i as f64).collect();
    m.regressor(&mut d, &x, &x, &x, &mut y);
    for j in 0..n {
        for i in 0..n {
            let mut k = Some(i);
            let mut carried = false;
            while let Some(b) = k {
                carried |= b == j;
                k = m.bodies[b].parent;
            }
            let block: f64 = (0..10).map(|c| y[(j, 10 * i + c)].abs()).sum();
            assert_eq!(block > 0.0, carried, "joint {j}, body {i}: {block}");
        }
    }
    assert_eq!(&m.parameter_names(true)[..3], ["m1", "mx1", "my1"]);
    assert_eq!(m.parameter_names(true)[10 * n], "fv1");
}

/// The regressor equals Pinocchio's `computeJointTorqueRegressor` column by column (same
/// parameter order, inertia about the joint frame) on files as ROS packages ship them, RNEA
/// equals Pinocchio's `rnea`, the mass matrix its `crba`, and forward dynamics (ABA and the
/// CRBA + Cholesky route) its `aba`, on the shipped 7-DOF arm and three arms of `evoloop robot
/// generate` too. Reference values from
/// Pinocchio 4.1.0 via scripts/pinocchio_regressor.py (tests/data/pinocchio_regressor.json).
#[test]
fn regressor_rnea_crba_and_aba_equal_pinocchio_on_urdf_arms() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("tests/data/pinocchio_regressor.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let vec = |x: &serde_json::Value| -> Vec<f64> {
        x.as_array()
            .unwrap()
            .iter()
            .map(|e| e.as_f64().unwrap())
            .collect()
    };
    let cases = v["cases"].as_array().unwrap();
    assert!(cases.len() >= 21);
    for robot in ["config/robots/arm7.urdf", "tests/robots/gen7_s13.urdf"] {
        assert!(cases.iter().any(|c| c["robot"] == robot), "{robot}");
    }
    for case in cases {
        let file = case["robot"].as_str().unwrap();
        let mut m = dynamics::load(&root.join(file)).unwrap();
        // Pinocchio's algorithms are rigid-body only (its model keeps URDF damping and friction
        // aside).
        m.clear_friction();
        let names: Vec<&str> = m.bodies.iter().map(|b| b.joint.as_str()).collect();
        let theirs: Vec<&str> = case["joints"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| j.as_str().unwrap())
            .collect();
        assert_eq!(names, theirs, "{file}: joint order");
        let n = m.dof();
        let (q, qd, qdd) = (vec(&case["q"]), vec(&case["qd"]), vec(&case["qdd"]));
        let mut d = m.data();
        let mut y = DMatrix::zeros(n, m.regressor_columns(false));
        m.regressor(&mut d, &q, &qd, &qdd, &mut y);
        let rows: Vec<Vec<f64>> = case["Y"].as_array().unwrap().iter().map(vec).collect();
        let scale = rows.iter().flatten().fold(1.0f64, |a, x| a.max(x.abs()));
        for (j, row) in rows.iter().enumerate() {
            for (c, expected) in row.iter().enumerate() {
                assert!(
                    (y[(j, c)] - expected).abs() <= 1e-9 * scale,
                    "{file}: Y[{j}, {}] = {} vs Pinocchio {expected}",
                    m.parameter_names(false)[c],
                    y[(j, c)]
                );
            }
        }
        let mut tau = vec![0.0; n];
        m.rnea(&mut d, &q, &qd, &qdd, &mut tau);
        for (j, expected) in vec(&case["tau"]).iter().enumerate() {
            assert!(
                (tau[j] - expected).abs() <= 1e-9 * (1.0 + expected.abs()),
                "{file}: tau[{j}] {} vs Pinocchio {expected}",
                tau[j]
            );
        }
        let big: Vec<Vec<f64>> = case["M"].as_array().unwrap().iter().map(vec).collect();
        let mm = m.mass_matrix(&mut d, &q).clone();
        for (i, row) in big.iter().enumerate() {
            for (j, expected) in row.iter().enumerate() {
                assert!(
                    (mm[(i, j)] - expected).abs() <= 1e-10 * (1.0 + expected.abs()),
                    "{file}: M[{i}, {j}] {} vs Pinocchio {expected}",
                    mm[(i, j)]
                );
            }
        }
        let tau_fd = vec(&case["tau_fd"]);
        let theirs = vec(&case["qdd_aba"]);
        let scale = theirs.iter().fold(1.0f64, |a, x| a.max(x.abs()));
        let (mut aba, mut crba) = (vec![0.0; n], vec![0.0; n]);
        m.forward_dynamics_aba(&mut d, &q, &qd, &tau_fd, &mut aba)
            .unwrap();
        m.forward_dynamics(&mut d, &q, &qd, &tau_fd, &mut crba)
            .unwrap();
        for j in 0..n {
            for (route, ours) in [("ABA", aba[j]), ("CRBA", crba[j])] {
                assert!(
                    (ours - theirs[j]).abs() <= 1e-9 * scale,
                    "{file}: {route} qdd[{j}] {ours} vs Pinocchio aba {}",
                    theirs[j]
                );
            }
        }
    }
}

/// Base parameters: as many as the rank of the stacked regressor (by SVD), every column either
/// base, unidentifiable or regrouped, and noise-free least squares on fresh states recovers the
/// base values beta = pi_b + K pi_d to 1e-8.
#[test]
fn base_parameters_have_the_regressor_rank_and_least_squares_recovers_them() {
    use evoloop::dynamics::base::{base_parameters, stacked_regressor};
    for m in arms() {
        for friction in [false, true] {
            let b = base_parameters(&m, friction, 60, 1);
            let w = stacked_regressor(&m, friction, 80, 2);
            let sv = w.clone().singular_values();
            let rank = sv.iter().filter(|s| **s > 1e-9 * sv.max()).count();
            assert_eq!(b.base_count(), rank, "{} (friction {friction})", m.name);
            assert_eq!(
                b.base_count() + b.unidentifiable.len() + b.combined.len(),
                b.names.len()
            );
            let pi = nalgebra::DVector::from_vec(m.parameters(friction));
            let tau = &w * &pi;
            let wb = b.base_columns(&w);
            let beta = wb.svd(true, true).solve(&tau, 1e-14).unwrap();
            for (k, base) in b.base.iter().enumerate() {
                assert!(
                    (beta[k] - base.value).abs() <= 1e-8 * (1.0 + base.value.abs()),
                    "{}: {} estimated {} vs {}",
                    m.name,
                    base.name,
                    beta[k],
                    base.value
                );
            }
        }
    }
    // The 6-DOF arm's first link turns about a vertical axis: only its Izz acts, regrouped.
    let b = base_parameters(&robot("industrial6.toml"), false, 60, 1);
    assert!(
        b.unidentifiable.contains(&"m1".to_string()),
        "{:?}",
        b.unidentifiable
    );
    assert!(!b.unidentifiable.contains(&"Izz1".to_string()));
}
