//! The executive's timer in a simulation: it sleeps on an inner timer (virtual time for
//! `--fast`, the OS clock in real time) and, each time it wakes, moves the simulated world to
//! the current time. So the world advances exactly between frames, on the executive's own
//! thread, and a virtual-time run is deterministic.

use crate::plant::Truth;
use crate::world::{DeviceLink, SimWorld};
use skyframe_core::executive::{Clock, FrameTimer};
use std::cell::RefCell;

/// Called with the world's ground truth at a fixed interval (the truth log).
pub type TruthTap = Box<dyn FnMut(u64, &Truth) + Send>;

pub struct SimTimer<T, L> {
    inner: T,
    /// None: a timer with no world (it only keeps time).
    state: RefCell<Option<State<L>>>,
}

struct State<L> {
    world: SimWorld,
    link: L,
    truth_every_ns: u64,
    next_truth_ns: u64,
    on_truth: Option<TruthTap>,
}

impl<T: FrameTimer, L: DeviceLink> SimTimer<T, L> {
    pub fn new(inner: T, world: SimWorld, link: L) -> Self {
        Self {
            inner,
            state: RefCell::new(Some(State {
                world,
                link,
                truth_every_ns: u64::MAX,
                next_truth_ns: 0,
                on_truth: None,
            })),
        }
    }

    /// A timer without a world: it only keeps time.
    pub fn without_world(inner: T) -> Self {
        Self {
            inner,
            state: RefCell::new(None),
        }
    }

    /// Hands the ground truth to `tap` every `every_ns` of simulated time.
    pub fn with_truth(self, every_ns: u64, tap: TruthTap) -> Self {
        if let Ok(mut s) = self.state.try_borrow_mut()
            && let Some(s) = s.as_mut()
        {
            s.truth_every_ns = every_ns.max(1);
            s.on_truth = Some(tap);
        }
        self
    }

    fn advance(&self) {
        let now = self.inner.now_ns();
        // Never re-entered: the executive thread alone calls the timer.
        let Ok(mut state) = self.state.try_borrow_mut() else {
            return;
        };
        let Some(state) = state.as_mut() else {
            return;
        };
        while state.next_truth_ns <= now {
            let t = state.next_truth_ns;
            state.world.advance_to(t, &mut state.link);
            if let Some(tap) = state.on_truth.as_mut() {
                tap(t, &state.world.truth());
            }
            state.next_truth_ns = state.next_truth_ns.saturating_add(state.truth_every_ns);
        }
        state.world.advance_to(now, &mut state.link);
    }

    /// Runs `f` on the world (scenario faults, statistics).
    pub fn with_world<R>(&self, f: impl FnOnce(&mut SimWorld) -> R) -> Option<R> {
        let mut state = self.state.try_borrow_mut().ok()?;
        state.as_mut().map(|s| f(&mut s.world))
    }
}

impl<T: FrameTimer, L: DeviceLink> Clock for SimTimer<T, L> {
    fn now_ns(&self) -> u64 {
        self.inner.now_ns()
    }

    fn spin_until(&self, t_ns: u64) {
        self.inner.spin_until(t_ns);
    }
}

impl<T: FrameTimer, L: DeviceLink> FrameTimer for SimTimer<T, L> {
    fn sleep_until(&self, t_ns: u64) {
        self.inner.sleep_until(t_ns);
        self.advance();
    }
}
