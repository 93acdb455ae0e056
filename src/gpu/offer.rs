//! A device that one thread opens and another adopts: the window opens its device on the
//! event-loop thread once the window exists, and the compose thread, which reconstructs,
//! runs on that same device so that the window can draw the reconstruction's textures
//! without copying them through the CPU (ARCHITECTURE.md, "One device on the master").
//!
//! The offer is decided once: a device, or none (the window could not open one, or its
//! adapter cannot run the reconstruction). Until then [`DeviceOffer::wait`] waits.

use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use super::GpuContext;

/// What the offer holds.
#[derive(Debug, Default)]
enum State {
    #[default]
    Pending,
    Offered(Arc<GpuContext>),
    Withdrawn,
}

/// A device offered once by one thread to another; cheap to clone (shared).
#[derive(Clone, Debug, Default)]
pub struct DeviceOffer {
    inner: Arc<(Mutex<State>, Condvar)>,
}

impl DeviceOffer {
    /// An offer not decided yet.
    pub fn new() -> Self {
        Self::default()
    }

    fn decide(&self, to: State) {
        let (state, changed) = &*self.inner;
        let mut state = state.lock().unwrap_or_else(|p| p.into_inner());
        if matches!(*state, State::Pending) {
            *state = to;
        }
        drop(state);
        changed.notify_all();
    }

    /// Offers `device`; ignored once the offer was decided.
    pub fn offer(&self, device: Arc<GpuContext>) {
        self.decide(State::Offered(device));
    }

    /// Says that no device will come; ignored once the offer was decided.
    pub fn withdraw(&self) {
        self.decide(State::Withdrawn);
    }

    /// The offered device, waiting up to `timeout` for the decision; `None` when it was
    /// withdrawn or not decided in time.
    pub fn wait(&self, timeout: Duration) -> Option<Arc<GpuContext>> {
        let (state, changed) = &*self.inner;
        let state = state.lock().unwrap_or_else(|p| p.into_inner());
        let (state, _) = changed
            .wait_timeout_while(state, timeout, |s| matches!(s, State::Pending))
            .unwrap_or_else(|p| p.into_inner());
        match &*state {
            State::Offered(device) => Some(Arc::clone(device)),
            State::Pending | State::Withdrawn => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_withdrawn_offer_gives_none_at_once_and_stays_withdrawn() {
        let offer = DeviceOffer::new();
        let waiter = {
            let offer = offer.clone();
            std::thread::spawn(move || offer.wait(Duration::from_secs(60)).is_none())
        };
        offer.withdraw();
        assert!(waiter.join().expect("waiter"), "withdrawn: no device");
        assert!(offer.wait(Duration::ZERO).is_none());
    }

    #[test]
    fn an_undecided_offer_times_out() {
        assert!(DeviceOffer::new().wait(Duration::from_millis(1)).is_none());
    }

    #[test]
    fn an_offered_device_reaches_the_waiting_thread() {
        // Needs an adapter; lavapipe counts. Without one there is nothing to offer.
        let ctx = match GpuContext::new() {
            Ok(ctx) => ctx,
            Err(err) => {
                let test = "an_offered_device_reaches_the_waiting_thread";
                crate::testing::skip(test, crate::testing::Missing::Adapter, err);
                return;
            }
        };
        let ctx = ctx.shared();
        let offer = DeviceOffer::new();
        let waiter = {
            let offer = offer.clone();
            std::thread::spawn(move || offer.wait(Duration::from_secs(60)))
        };
        offer.offer(Arc::clone(&ctx));
        offer.withdraw(); // too late: the offer stands
        let got = waiter.join().expect("waiter").expect("the offered device");
        assert!(Arc::ptr_eq(&got, &ctx));
    }
}
