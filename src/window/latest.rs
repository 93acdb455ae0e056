//! A hand-off slot that keeps only the newest value.
//!
//! The master shows frames at its own pace and the window draws at the display's; neither
//! may wait for the other (issue 5). The producer replaces whatever is in the slot and
//! never blocks for long (one short mutex hold); the consumer takes the newest value when
//! it is ready for one, and values it never saw are counted as replaced, not queued.

use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::Duration;

/// Newest-value slot shared by one producer and one consumer thread.
#[derive(Debug, Default)]
pub struct Latest<T> {
    inner: Mutex<LatestState<T>>,
    ready: Condvar,
}

#[derive(Debug)]
struct LatestState<T> {
    value: Option<T>,
    /// Values put but overwritten before anyone took them.
    replaced: u64,
    /// Set once; wakes a waiting consumer for good.
    closed: bool,
}

impl<T> Default for LatestState<T> {
    fn default() -> Self {
        Self { value: None, replaced: 0, closed: false }
    }
}

/// What [`Latest::wait`] found.
#[derive(Debug, PartialEq, Eq)]
pub enum Waited<T> {
    Value(T),
    TimedOut,
    Closed,
}

impl<T> Latest<T> {
    /// An empty, open slot.
    pub fn new() -> Self {
        Self { inner: Mutex::new(LatestState::default()), ready: Condvar::new() }
    }

    // A panic while the lock was held cannot leave the slot inconsistent (every update is a
    // single assignment), so a poisoned lock is simply taken over.
    fn lock(&self) -> MutexGuard<'_, LatestState<T>> {
        self.inner.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Puts `value`, replacing any value not yet taken. Returns false (and drops the value)
    /// once the slot is closed.
    pub fn put(&self, value: T) -> bool {
        self.put_merging(value, |_, _| {})
    }

    /// Like [`Latest::put`], but a value not yet taken is first handed to `merge` with the
    /// new one, for what it carries that must not be lost with it (the edits a replaced
    /// frame was the first to show).
    pub fn put_merging(&self, mut value: T, merge: impl FnOnce(T, &mut T)) -> bool {
        let mut slot = self.lock();
        if slot.closed {
            return false;
        }
        if let Some(old) = slot.value.take() {
            merge(old, &mut value);
            slot.replaced += 1;
        }
        slot.value = Some(value);
        drop(slot);
        self.ready.notify_one();
        true
    }

    /// Takes the newest value, if any, without waiting.
    pub fn take(&self) -> Option<T> {
        self.lock().value.take()
    }

    /// Waits up to `timeout` for a value; a value already there is returned at once, even
    /// after the slot was closed.
    pub fn wait(&self, timeout: Duration) -> Waited<T> {
        let slot = self.lock();
        let (mut slot, _) = self
            .ready
            .wait_timeout_while(slot, timeout, |s| s.value.is_none() && !s.closed)
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        match slot.value.take() {
            Some(value) => Waited::Value(value),
            None if slot.closed => Waited::Closed,
            None => Waited::TimedOut,
        }
    }

    /// Closes the slot: later puts are refused and a waiting consumer wakes up.
    pub fn close(&self) {
        self.lock().closed = true;
        self.ready.notify_all();
    }

    /// True once [`Latest::close`] was called.
    pub fn is_closed(&self) -> bool {
        self.lock().closed
    }

    /// How many values were overwritten before being taken.
    pub fn replaced(&self) -> u64 {
        self.lock().replaced
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn keeps_only_the_newest_and_counts_the_rest() {
        let slot = Latest::new();
        assert!(slot.put(1));
        assert!(slot.put(2));
        assert!(slot.put(3));
        assert_eq!(slot.take(), Some(3));
        assert_eq!(slot.take(), None);
        assert_eq!(slot.replaced(), 2);
    }

    #[test]
    fn a_replaced_value_is_merged_into_the_newer_one() {
        let slot = Latest::new();
        let keep = |old: Vec<u32>, new: &mut Vec<u32>| new.splice(0..0, old).for_each(drop);
        assert!(slot.put_merging(vec![1], keep));
        assert!(slot.put_merging(vec![2, 3], keep));
        assert_eq!(slot.take(), Some(vec![1, 2, 3]));
        assert!(slot.put_merging(vec![4], keep));
        assert_eq!(slot.take(), Some(vec![4]), "a value taken is not merged again");
        assert_eq!(slot.replaced(), 1);
    }

    #[test]
    fn wait_times_out_when_empty() {
        let slot: Latest<u32> = Latest::new();
        assert_eq!(slot.wait(Duration::from_millis(1)), Waited::TimedOut);
    }

    #[test]
    fn wait_wakes_on_put_from_another_thread() {
        let slot = Arc::new(Latest::new());
        let producer = {
            let slot = Arc::clone(&slot);
            std::thread::spawn(move || slot.put(7))
        };
        // Generous bound: the test asserts the value, not how fast it came.
        assert_eq!(slot.wait(Duration::from_secs(30)), Waited::Value(7));
        assert!(producer.join().expect("producer thread"));
    }

    #[test]
    fn close_refuses_puts_and_wakes_waiters_but_keeps_a_pending_value() {
        let slot = Latest::new();
        assert!(slot.put(1));
        slot.close();
        assert!(slot.is_closed());
        assert!(!slot.put(2));
        assert_eq!(slot.wait(Duration::from_secs(30)), Waited::Value(1));
        assert_eq!(slot.wait(Duration::from_secs(30)), Waited::Closed);
    }
}
