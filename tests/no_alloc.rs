//! The hot paths allocate nothing per call: counted with a global allocator.

use orbitflex::algorithms::{self, Data};
use orbitflex::integrate::{simulate_into, Chunks, Drive, Run, Unobserved};
use orbitflex::testing::{random_chain, random_state};
use orbitflex::{
    ArmWorkspace, FlexibleArm, FlexibleJoints, Inputs, Loads, MotorPD, RigidState, Schedule,
    StateSpec, Wrenches,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    // Per thread, so the test harness's other threads do not count; const-initialised, so
    // touching it does not allocate.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count_one() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_one();
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_one();
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(Cell::get);
    f();
    ALLOCATIONS.with(Cell::get) - before
}

#[test]
fn hot_paths_do_not_allocate() {
    let robot = random_chain(12, 3);
    let n = robot.dof();
    let (q, v, qd) = random_state(&robot, 3);
    let tau = vec![0.5; n];
    let w = [0.1; 6];
    let state = RigidState::new(&q, &v, &qd);
    let loads = Loads::from_slices(Some(&w), Some(&w)).unwrap();
    let mut data = Data::new(&robot);
    let mut poses = vec![0.0; 7 * robot.frames().len()];
    let base = [0.1, 0.2, 0.3, 0.0, 0.6, 0.0, 0.8];
    assert_eq!(
        allocations(|| {
            algorithms::frame_poses(&robot, &mut data, &base, &q, &mut poses).unwrap();
        }),
        0,
        "frame_poses"
    );
    assert_eq!(
        allocations(|| {
            algorithms::aba(&robot, &mut data, &state, &tau, &loads).unwrap();
        }),
        0,
        "aba"
    );
    assert_eq!(
        allocations(|| {
            algorithms::rnea(&robot, &mut data, &state, &w, &tau, &w).unwrap();
        }),
        0,
        "rnea"
    );
    // The dense mass matrix is the one O(n²) buffer: allocated by the first crba, not by Data::new.
    assert_eq!(data.mass_matrix.len(), 0, "Data::new made a dense matrix");
    assert_eq!(
        allocations(|| {
            algorithms::crba(&robot, &mut data, &q).unwrap();
        }),
        1,
        "first crba"
    );
    assert_eq!(
        allocations(|| {
            algorithms::crba(&robot, &mut data, &q).unwrap();
        }),
        0,
        "crba"
    );
    assert_eq!(
        allocations(|| {
            algorithms::bias_forces(&robot, &mut data, &state).unwrap();
        }),
        0,
        "bias"
    );
    // The derivatives' O(n²) buffers come with the first call, then are reused.
    algorithms::aba_derivatives(&robot, &mut data, &state, &tau, &loads).unwrap();
    assert_eq!(
        allocations(|| {
            algorithms::aba_derivatives(&robot, &mut data, &state, &tau, &loads).unwrap();
            algorithms::rnea_derivatives(&robot, &mut data, &state, &w, &tau, &w).unwrap();
        }),
        0,
        "derivatives"
    );
    assert_eq!(
        allocations(|| {
            algorithms::ee_jacobian(&robot, &mut data, &q, 0).unwrap();
        }),
        0,
        "jacobian"
    );
    assert_eq!(
        allocations(|| {
            algorithms::momentum(&robot, &mut data, &state).unwrap();
        }),
        0,
        "momentum"
    );

    let arm = FlexibleArm::new(
        robot,
        FlexibleJoints::uniform(n, 500.0, 0.1, 0.5, 0.1).unwrap(),
    )
    .unwrap();
    let mut ws = ArmWorkspace::new(&arm);
    let mut x = arm
        .state(&StateSpec {
            q: Some(&q),
            qd: Some(&qd),
            base_twist: Some(&v),
            ..StateSpec::default()
        })
        .unwrap();
    let inputs = Inputs {
        u: &tau,
        loads,
        wheel_torque: &[],
    };
    let mut xdot = vec![0.0; x.len()];
    assert_eq!(
        allocations(|| arm.derivative(&mut ws, &x, &inputs, &mut xdot).unwrap()),
        0,
        "derivative"
    );
    assert_eq!(
        allocations(|| arm.step(&mut ws, &mut x, 1e-3, &inputs).unwrap()),
        0,
        "step"
    );
    assert_eq!(
        allocations(|| {
            arm.energy(&mut ws, &x);
            arm.momentum(&mut ws, &x);
        }),
        0,
        "diagnostics"
    );

    // simulate: a fixed number of allocations (workspace and output), whatever the step count.
    let pd = MotorPD::new(
        vec![10.0; n],
        vec![1.0; n],
        Schedule::Constant(vec![0.1; n]),
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let count = |steps: usize| {
        let mut pd = pd.clone();
        allocations(|| {
            arm.simulate(
                &x,
                1e-4,
                steps,
                &mut pd,
                &Wrenches {
                    base: Schedule::Zero,
                    ee: Schedule::Constant(w.to_vec()),
                    wheel_torque: orbitflex::Schedule::Zero,
                },
            )
            .unwrap();
        })
    };
    assert_eq!(count(10), count(1000), "simulate allocates per step");

    // Streaming into a reused chunk buffer: the run's own few allocations (workspace, state,
    // torque and last-good-state buffers), none per step or per chunk; the buffer, made once,
    // is not counted.
    let mut wrenches = Wrenches {
        base: Schedule::Zero,
        ee: Schedule::Constant(w.to_vec()),
        wheel_torque: orbitflex::Schedule::Zero,
    };
    let mut rows = 0;
    let mut sink = Chunks::new(arm.layout(), 16, |chunk| {
        rows += chunk.len();
        Ok(())
    })
    .unwrap();
    let mut stream = |steps: usize, every: usize| {
        let mut pd = pd.clone();
        allocations(|| {
            simulate_into(
                &arm,
                &Run::new(&x, 1e-4, steps).recording_every(every),
                &mut Drive::new(&mut pd, &mut wrenches),
                &mut Unobserved,
                &mut sink,
            )
            .unwrap();
        })
    };
    let (short, long) = (stream(10, 3), stream(2000, 3)); // 5 rows in 1 chunk; 668 in 42 chunks
    assert_eq!(
        short, long,
        "a streaming run allocates per step or per chunk"
    );
    assert_eq!(stream(2000, 1), stream(10, 1), "record_every = 1");
    drop(sink);
    assert_eq!(rows, 5 + 668 + 2001 + 11);
}

/// The same, with the portable copies chosen by `ORBITFLEX_PORTABLE=1` (the README's test
/// command run that way must pass): reading the variable allocates, so the choice is made when a
/// workspace is built, not in the first hot call. Runs the test above in a child process, since
/// the choice is made once per process.
#[test]
fn hot_paths_do_not_allocate_in_the_portable_copies_either() {
    if std::env::var_os("ORBITFLEX_PORTABLE").is_some() {
        return; // this process already runs one way; the test above covers it
    }
    let output = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "hot_paths_do_not_allocate",
            "--test-threads",
            "1",
        ])
        .env("ORBITFLEX_PORTABLE", "1")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success() && text.contains("1 passed"),
        "{text}{}",
        String::from_utf8_lossy(&output.stderr)
    );
}
