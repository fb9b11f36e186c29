//! Random models and states for tests and benchmarks (in the spirit of spatial_v2's `autoTree`).
//!
//! Chains get awkward features on purpose: unaligned unit axes, rotated joint origins, offset
//! centres of mass and rotated, fully populated inertias. A small deterministic generator keeps
//! this module free of dev-dependencies.

use crate::model::{Robot, RobotBuilder};
use crate::spatial::{rotation_about_axis, Inertia, Mat3, Transform, Vec3};

/// A tiny deterministic generator (SplitMix64), enough for test inputs.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// Seeded generator.
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_add(0x9E37_79B9_7F4A_7C15))
    }
    /// Uniform in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    /// `n` numbers uniform in `[lo, hi)`.
    pub fn vector(&mut self, n: usize, lo: f64, hi: f64) -> Vec<f64> {
        (0..n).map(|_| self.range(lo, hi)).collect()
    }
    /// A random unit vector.
    pub fn unit(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }
    /// A random rotation.
    pub fn rotation(&mut self) -> Mat3 {
        let axis = self.unit();
        rotation_about_axis(&axis, self.range(-3.1, 3.1))
    }
    /// A random physical inertia: mass in `[0.5, 5)` kg, COM offset up to 0.3 m, rotated
    /// principal moments that satisfy the triangle inequality.
    pub fn inertia(&mut self) -> Inertia {
        let mass = self.range(0.5, 5.0);
        let a = self.range(0.02, 0.2);
        let b = self.range(0.02, 0.2);
        let c = self.range((a - b).abs() + 0.01, a + b);
        let r = self.rotation();
        let about_com = r * Mat3::from_diagonal(&Vec3::new(a, b, c)) * r.transpose() * mass;
        let com = Vec3::new(
            self.range(-0.3, 0.3),
            self.range(-0.3, 0.3),
            self.range(-0.3, 0.3),
        );
        Inertia::from_com(mass, com, about_com)
    }
}

/// A random floating-base chain with `n` revolute joints (seeded, reproducible): base of
/// 20–60 kg, links 0.2–0.6 m apart with rotated origins, random axes, and a rotated, offset
/// EE frame.
pub fn random_chain(n: usize, seed: u64) -> Robot {
    let mut rng = Rng::new(seed);
    let base_mass = rng.range(20.0, 60.0);
    let base = Inertia::from_com(
        base_mass,
        Vec3::new(
            rng.range(-0.1, 0.1),
            rng.range(-0.1, 0.1),
            rng.range(-0.1, 0.1),
        ),
        Mat3::from_diagonal(&Vec3::new(
            rng.range(2.0, 4.0),
            rng.range(2.0, 4.0),
            rng.range(2.0, 4.0),
        )) * (base_mass / 6.0),
    );
    let mut builder = RobotBuilder::new(&format!("random_chain_{n}_{seed}"), "base", base);
    for i in 0..n {
        let offset = rng.unit() * rng.range(0.2, 0.6);
        let origin = Transform::new(rng.rotation().transpose(), offset);
        let axis = rng.unit();
        let inertia = rng.inertia();
        builder = builder.joint(
            &format!("joint{}", i + 1),
            origin,
            axis,
            &format!("link{}", i + 1),
            inertia,
        );
    }
    let ee = Transform::new(rng.rotation(), rng.unit() * rng.range(0.05, 0.3));
    builder
        .ee("ee", ee)
        .build()
        .expect("random chains are valid")
}

/// The branched tree of [`random_tree`]: body 1 is a trunk carrying two branches (from bodies 2
/// and 6), the EE frame on body 5 (path 5 → 4 → 2 → 1 → base; bodies 3, 6, 7 are off it).
pub const TREE_ONE_TRUNK: (&[usize], usize) = (&[0, 0, 1, 2, 2, 4, 1, 6], 5);

/// Three arms on the base (bodies 1, 6 and 9), the first forked at body 1, the EE frame on body 5
/// (path 5 → 4 → 1 → base).
pub const TREE_THREE_ARMS: (&[usize], usize) = (&[0, 0, 1, 2, 1, 4, 0, 6, 6, 0], 5);

/// A random branched tree (seeded): the bodies of [`random_chain`] re-hung from `parents`
/// (depth-first: `parents[i]` is `i − 1` or one of its ancestors; entry 0 unused) with the EE
/// frame on body `ee_body`, for checking that the recursions follow `parents` rather than
/// assuming a chain. `shape` is one of [`TREE_ONE_TRUNK`], [`TREE_THREE_ARMS`] or any
/// `(parents, ee_body)` of that form.
pub fn random_tree(shape: (&[usize], usize), seed: u64) -> Robot {
    let (parents, ee_body) = shape;
    assert!(parents.iter().enumerate().skip(1).all(|(i, &p)| p < i) && ee_body < parents.len());
    let mut robot = random_chain(parents.len() - 1, seed);
    robot.parents = parents.to_vec();
    robot.ees[0].body = ee_body;
    robot.name = format!("random_tree_{seed}");
    robot.link_frames = Vec::new();
    crate::model::RobotBuilder::from_robot(robot)
        .build()
        .expect("random trees are valid")
}

/// [`random_tree`] with one end-effector on every leaf body (a random placement each) instead of
/// one on `ee_body`.
pub fn random_tree_all_leaves(parents: &[usize], seed: u64) -> Robot {
    let robot = random_tree((parents, parents.len() - 1), seed);
    let mut rng = Rng::new(seed ^ 0x5eed);
    let n = parents.len() - 1;
    let ees = (1..=n)
        .filter(|&b| (b + 1..=n).all(|k| parents[k] != b))
        .map(|b| crate::model::EndEffector {
            link: format!("ee{b}"),
            body: b,
            transform: Transform::new(rng.rotation(), rng.unit() * rng.range(0.05, 0.3)),
        })
        .collect();
    let mut robot = Robot { ees, ..robot };
    robot.link_frames = Vec::new();
    crate::model::RobotBuilder::from_robot(robot)
        .build()
        .expect("random trees are valid")
}

/// Random flexible-joint parameters for `n` joints (seeded): stiffness 200–800 N·m/rad, damping
/// 0.05–0.2 N·m·s/rad, motor inertia 0.1–1 kg·m², motor damping 0.1–0.5 N·m·s/rad.
pub fn random_joints(n: usize, seed: u64) -> crate::FlexibleJoints {
    let mut rng = Rng::new(seed);
    crate::FlexibleJoints::new(
        rng.vector(n, 200.0, 800.0),
        rng.vector(n, 0.05, 0.2),
        rng.vector(n, 0.1, 1.0),
        rng.vector(n, 0.1, 0.5),
    )
    .expect("positive parameters")
}

/// A random state `(q, base_twist, qd)` for `robot`: angles in ±π, rates in ±1.
pub fn random_state(robot: &Robot, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut rng = Rng::new(seed ^ 0xABCD);
    let n = robot.dof();
    (
        rng.vector(n, -3.1, 3.1),
        rng.vector(6, -1.0, 1.0),
        rng.vector(n, -1.0, 1.0),
    )
}

/// `k` random reaction wheels (seeded): unit axes in random directions (not aligned with the
/// base axes), centres within 0.8 m of the base origin, 1–10 kg, `J_s` 0.01–0.1 kg·m², `J_t`
/// between `J_s/2` and `J_s`, friction 0–0.01 N·m·s, torque limit `max_torque` and speed limit
/// 1e4 rad/s.
pub fn random_wheels(k: usize, seed: u64, max_torque: f64) -> crate::flex::ReactionWheels {
    let mut rng = Rng::new(seed);
    let wheels = (0..k)
        .map(|_| {
            let spin = rng.range(0.01, 0.1);
            let a = rng.unit();
            crate::flex::Wheel {
                axis: [a.x, a.y, a.z],
                position: [
                    rng.range(-0.8, 0.8),
                    rng.range(-0.8, 0.8),
                    rng.range(-0.8, 0.8),
                ],
                mass: rng.range(1.0, 10.0),
                spin_inertia: spin,
                transverse_inertia: rng.range(0.5 * spin, spin),
                max_torque,
                max_speed: 1e4,
                friction: rng.range(0.0, 0.01),
            }
        })
        .collect();
    crate::flex::ReactionWheels::new(wheels).expect("valid random wheels")
}
