//! The little spatial (6-D) algebra the recursions need, on glam's 3-D types: motion and force
//! vectors as pairs of 3-vectors, Plücker transforms as a rotation and a translation, and rigid-body
//! inertias in the compact form (m, h = m c, I_o). Conventions follow Featherstone, *Rigid Body
//! Dynamics Algorithms* (2008), chapter 2, with the angular part first.

use glam::{DMat3, DVec3};

/// A spatial motion vector (angular velocity w, linear velocity v of the body point at the
/// frame's origin), in the coordinates of one body frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Motion {
    /// Angular part: the angular velocity (or acceleration).
    pub w: DVec3,
    /// Linear part: the velocity (or acceleration) of the body point at the frame's origin.
    pub v: DVec3,
}

/// A spatial force (moment n about the frame's origin, force f), in one body frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Force {
    /// Moment about the frame's origin (N m).
    pub n: DVec3,
    /// Force (N).
    pub f: DVec3,
}

impl Motion {
    /// No motion.
    pub const ZERO: Motion = Motion {
        w: DVec3::ZERO,
        v: DVec3::ZERO,
    };

    /// Both parts times `s`.
    pub fn scaled(self, s: f64) -> Motion {
        Motion {
            w: self.w * s,
            v: self.v * s,
        }
    }

    /// The motion cross product self ×m m.
    pub fn cross_motion(self, m: Motion) -> Motion {
        Motion {
            w: self.w.cross(m.w),
            v: self.w.cross(m.v) + self.v.cross(m.w),
        }
    }

    /// The force cross product self ×* f.
    pub fn cross_force(self, f: Force) -> Force {
        Force {
            n: self.w.cross(f.n) + self.v.cross(f.f),
            f: self.w.cross(f.f),
        }
    }

    /// The scalar product with a force (power).
    pub fn dot(self, f: Force) -> f64 {
        self.w.dot(f.n) + self.v.dot(f.f)
    }
}

impl Force {
    /// No force.
    pub const ZERO: Force = Force {
        n: DVec3::ZERO,
        f: DVec3::ZERO,
    };

    /// Both parts times `s`.
    pub fn scaled(self, s: f64) -> Force {
        Force {
            n: self.n * s,
            f: self.f * s,
        }
    }
}

/// A Plücker transform from a parent frame to a child frame: `e` rotates parent coordinates into
/// child coordinates, `r` is the child's origin in parent coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// Rotation from parent coordinates into child coordinates.
    pub e: DMat3,
    /// The child frame's origin in parent coordinates (m).
    pub r: DVec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Transform {
    /// The child frame is the parent frame.
    pub const IDENTITY: Transform = Transform {
        e: DMat3::IDENTITY,
        r: DVec3::ZERO,
    };

    /// The transform to a frame placed at `pos` with axes `rot` (columns = the child's axes in
    /// parent coordinates), as URDF `<origin>` and D-H rows describe it.
    pub fn from_placement(rot: DMat3, pos: DVec3) -> Transform {
        Transform {
            e: rot.transpose(),
            r: pos,
        }
    }

    /// The child frame's axes in parent coordinates (inverse of `from_placement`).
    pub fn rotation(&self) -> DMat3 {
        self.e.transpose()
    }

    /// `self` then `next` (parent → self's child → next's child).
    pub fn then(&self, next: &Transform) -> Transform {
        Transform {
            e: next.e * self.e,
            r: self.r + self.e.transpose() * next.r,
        }
    }

    /// A motion vector from parent to child coordinates.
    pub fn apply_motion(&self, m: Motion) -> Motion {
        Motion {
            w: self.e * m.w,
            v: self.e * (m.v - self.r.cross(m.w)),
        }
    }

    /// A force from child to parent coordinates (the transpose of the motion transform).
    pub fn apply_transpose_force(&self, f: Force) -> Force {
        let n = self.e.transpose() * f.n;
        let fp = self.e.transpose() * f.f;
        Force {
            n: n + self.r.cross(fp),
            f: fp,
        }
    }

    /// A point given in child coordinates, in parent coordinates.
    pub fn point_to_parent(&self, p: DVec3) -> DVec3 {
        self.r + self.e.transpose() * p
    }
}

/// A rigid-body inertia about a frame's origin: mass, first moment h = m c, and the rotational
/// inertia about the origin. This form adds by plain addition and needs no division by the mass,
/// so massless bodies compose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertia {
    /// Mass (kg).
    pub m: f64,
    /// First moment of mass about the frame's origin, h = m c with c the centre of mass (kg m).
    pub h: DVec3,
    /// Rotational inertia about the frame's origin (kg m^2).
    pub i: DMat3,
}

impl Default for Inertia {
    fn default() -> Self {
        Self::ZERO
    }
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

impl Inertia {
    /// No mass and no inertia.
    pub const ZERO: Inertia = Inertia {
        m: 0.0,
        h: DVec3::ZERO,
        i: DMat3::ZERO,
    };

    /// From mass, centre of mass and the inertia tensor about the centre of mass (parallel axis).
    pub fn from_com(m: f64, com: DVec3, i_com: DMat3) -> Inertia {
        Inertia {
            m,
            h: com * m,
            i: i_com + (DMat3::IDENTITY * com.length_squared() - outer(com, com)) * m,
        }
    }

    /// The centre of mass (origin for a massless body).
    pub fn com(&self) -> DVec3 {
        if self.m > 0.0 {
            self.h / self.m
        } else {
            DVec3::ZERO
        }
    }

    /// The inertia about the centre of mass.
    pub fn i_com(&self) -> DMat3 {
        let c = self.com();
        self.i - (DMat3::IDENTITY * c.length_squared() - outer(c, c)) * self.m
    }

    /// The momentum I·m.
    pub fn apply(&self, m: Motion) -> Force {
        Force {
            n: self.i * m.w + self.h.cross(m.v),
            f: m.v * self.m - self.h.cross(m.w),
        }
    }

    /// `apply` to a unit rotation about z (a revolute joint about z: S = [z; 0]), written out:
    /// the inertia's third column and -h × z. The general product's other terms are products
    /// with exact zeros, so the values are its values (up to the sign of a zero; tested).
    #[inline]
    pub fn apply_z(&self) -> Force {
        Force {
            n: self.i.z_axis,
            f: DVec3::new(-self.h.y, self.h.x, 0.0),
        }
    }

    /// This inertia (given in the child frame of `x`) in the parent frame: Xᵀ I X.
    pub fn to_parent(&self, x: &Transform) -> Inertia {
        let et = x.e.transpose();
        let h = et * self.h;
        let i_rot = et * self.i * x.e;
        let r = x.r;
        // Shift of the reference point from the child origin (at r) to the parent origin:
        // I_O = I_P - m r̃ r̃ - r̃ h̃ - h̃ r̃, with ã b̃ = b aᵀ - (a·b) 1.
        let rh = r.dot(h);
        let i = i_rot
            - (outer(r, r) - DMat3::IDENTITY * r.length_squared()) * self.m
            - (outer(h, r) + outer(r, h) - DMat3::IDENTITY * (2.0 * rh));
        Inertia {
            m: self.m,
            h: h + r * self.m,
            i,
        }
    }
}

/// An articulated-body inertia (ABA): a general symmetric 6 x 6 [[A, B], [Bᵀ, C]] mapping a
/// motion [w; v] to a force [n; f], kept as three 3 x 3 blocks (A and C symmetric) so that the
/// transform to the parent costs 3 x 3 products instead of two 6 x 6 ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Articulated {
    /// Block A: moment from angular motion (symmetric).
    pub a: DMat3,
    /// Block B: moment from linear motion (Bᵀ gives force from angular motion).
    pub b: DMat3,
    /// Block C: force from linear motion (symmetric).
    pub c: DMat3,
}

/// r× as a matrix: (r×) v = r × v.
fn skew(r: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, r.z, -r.y),
        DVec3::new(-r.z, 0.0, r.x),
        DVec3::new(r.y, -r.x, 0.0),
    )
}

impl Articulated {
    /// The zero inertia.
    pub const ZERO: Articulated = Articulated {
        a: DMat3::ZERO,
        b: DMat3::ZERO,
        c: DMat3::ZERO,
    };

    /// A rigid body's inertia: A = I_o, B = h×, C = m 1 (`Inertia::apply`).
    pub fn rigid(i: &Inertia) -> Articulated {
        Articulated {
            a: i.i,
            b: skew(i.h),
            c: DMat3::IDENTITY * i.m,
        }
    }

    /// The force for motion `m`: [A w + B v; Bᵀ w + C v].
    pub fn apply(&self, m: Motion) -> Force {
        Force {
            n: self.a * m.w + self.b * m.v,
            f: self.b.transpose() * m.w + self.c * m.v,
        }
    }

    /// self - u uᵀ / d (the joint's motion projected out, Featherstone's I^a = I^A - U D⁻¹ Uᵀ).
    pub fn minus_outer(&self, u: Force, d_inv: f64) -> Articulated {
        let (un, uf) = (u.n * d_inv, u.f);
        Articulated {
            a: self.a - outer(un, u.n),
            b: self.b - outer(un, uf),
            c: self.c - outer(uf * d_inv, uf),
        }
    }

    /// This inertia (given in the child frame of `x`) in the parent frame: Xᵀ I X, with
    /// X = [[E, 0], [0, E]] [[1, 0], [-r×, 1]]: rotate each block by E, then shift by r.
    pub fn to_parent(&self, x: &Transform) -> Articulated {
        let (e, et) = (x.e, x.e.transpose());
        let a = et * self.a * e;
        let b = et * self.b * e;
        let c = et * self.c * e;
        let rx = skew(x.r);
        let brx = b * rx;
        Articulated {
            a: a - brx - brx.transpose() - rx * c * rx,
            b: b + rx * c,
            c,
        }
    }
}

impl std::ops::Add for Articulated {
    type Output = Articulated;
    fn add(self, o: Articulated) -> Articulated {
        Articulated {
            a: self.a + o.a,
            b: self.b + o.b,
            c: self.c + o.c,
        }
    }
}

impl std::ops::Add for Motion {
    type Output = Motion;
    fn add(self, o: Motion) -> Motion {
        Motion {
            w: self.w + o.w,
            v: self.v + o.v,
        }
    }
}

impl std::ops::Add for Force {
    type Output = Force;
    fn add(self, o: Force) -> Force {
        Force {
            n: self.n + o.n,
            f: self.f + o.f,
        }
    }
}

impl std::ops::Add for Inertia {
    type Output = Inertia;
    fn add(self, o: Inertia) -> Inertia {
        Inertia {
            m: self.m + o.m,
            h: self.h + o.h,
            i: self.i + o.i,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_body() -> Inertia {
        Inertia::from_com(
            2.5,
            DVec3::new(0.1, 0.2, -0.05),
            DMat3::from_diagonal(DVec3::new(0.3, 0.2, 0.1)),
        )
    }

    fn sample_motion() -> Motion {
        Motion {
            w: DVec3::new(0.3, 1.1, -0.2),
            v: DVec3::new(-0.5, 0.25, 0.8),
        }
    }

    fn sample_transform() -> Transform {
        let rot = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 0.7);
        Transform::from_placement(rot, DVec3::new(0.3, -0.2, 0.9))
    }

    #[test]
    fn power_is_invariant_under_transforms() {
        let x = sample_transform();
        let m = Motion {
            w: DVec3::new(0.1, -0.4, 2.0),
            v: DVec3::new(1.0, 0.5, -0.3),
        };
        let f = Force {
            n: DVec3::new(-0.7, 0.2, 0.1),
            f: DVec3::new(0.4, 3.0, -1.0),
        };
        // (X m) · f_child = m · (Xᵀ f_child)
        let lhs = x.apply_motion(m).dot(f);
        let rhs = m.dot(x.apply_transpose_force(f));
        assert!((lhs - rhs).abs() < 1e-12);
    }

    #[test]
    fn inertia_transform_matches_momentum_transform() {
        // Xᵀ I X m (via to_parent) equals Xᵀ (I (X m)) for any motion m.
        let (x, body, m) = (sample_transform(), sample_body(), sample_motion());
        let a = body.to_parent(&x).apply(m);
        let b = x.apply_transpose_force(body.apply(x.apply_motion(m)));
        assert!((a.n - b.n).length() < 1e-12 && (a.f - b.f).length() < 1e-12);
        // Round trip of the centre-of-mass form.
        let back = body.i_com();
        assert!((back - DMat3::from_diagonal(DVec3::new(0.3, 0.2, 0.1)))
            .abs_diff_eq(DMat3::ZERO, 1e-12));
    }

    /// The articulated form agrees with the rigid one on rigid bodies (apply and transform),
    /// and its transform is Xᵀ I X on a general symmetric inertia too.
    #[test]
    fn articulated_inertia_transforms_as_x_transpose_i_x() {
        let (x, body, m) = (sample_transform(), sample_body(), sample_motion());
        let close = |a: Force, b: Force| (a.n - b.n).length() + (a.f - b.f).length() < 1e-12;
        let art = Articulated::rigid(&body);
        assert!(close(art.apply(m), body.apply(m)));
        assert!(close(
            art.to_parent(&x).apply(m),
            body.to_parent(&x).apply(m)
        ));
        // Not rigid: a projection taken out, as ABA does.
        let u = art.apply(Motion {
            w: DVec3::new(0.0, 0.6, 0.8),
            v: DVec3::ZERO,
        });
        let general = art.minus_outer(u, 0.37);
        let a = general.to_parent(&x).apply(m);
        let b = x.apply_transpose_force(general.apply(x.apply_motion(m)));
        assert!(close(a, b));
    }

    /// `apply_z` gives `apply`'s values on S = [z; 0] exactly (== holds for 0.0 against -0.0,
    /// the only difference a dropped zero product can make), on random bodies of mixed
    /// magnitudes and signs and on bodies with exact zeros.
    #[test]
    fn apply_z_equals_the_general_product_exactly() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut v = || {
            let scale = 10f64.powi(rng.gen_range(-3..3));
            DVec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            ) * scale
        };
        let z = Motion {
            w: DVec3::Z,
            v: DVec3::ZERO,
        };
        for k in 0..2000 {
            let (a, b, c) = (v(), v(), v());
            let mut body = Inertia {
                m: c.x.abs(),
                h: a,
                i: DMat3::from_cols(b, c, a.cross(b)),
            };
            // Exact zeros too, where only a sign can differ: a centre of mass on the z axis, a
            // diagonal inertia, no mass.
            if k % 4 == 0 {
                body.h = DVec3::new(0.0, -0.0, a.z);
                body.i = DMat3::from_diagonal(b.abs());
                body.m = 0.0;
            }
            assert_eq!(body.apply_z(), body.apply(z));
        }
    }

    #[test]
    fn composition_is_sequential_application() {
        let a = sample_transform();
        let b = Transform::from_placement(DMat3::from_rotation_z(-1.2), DVec3::new(0.0, 0.5, 0.1));
        let m = Motion {
            w: DVec3::new(0.2, 0.0, 1.0),
            v: DVec3::new(0.0, -1.0, 0.3),
        };
        let ab = a.then(&b).apply_motion(m);
        let seq = b.apply_motion(a.apply_motion(m));
        assert!((ab.w - seq.w).length() < 1e-12 && (ab.v - seq.v).length() < 1e-12);
    }
}
