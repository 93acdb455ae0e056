//! G-buffers computed ahead: as soon as the scene state changes, the new state's
//! G-buffer is computed on a thread of its own, while the workers render the new view,
//! instead of after the display decided to show its first frame.
//!
//! Measured first (issue 18, `gbuffer_ms` in `stats.jsonl`): during a steady orbit every
//! shown frame is of a new state, and its G-buffer (one primary ray per pixel on the CPU)
//! was more than half of the compose time that every edit's latency paid after the
//! decision. Only the newest state wanted is computed (a state superseded before its turn
//! is never computed: edits may come faster than G-buffers), and the last few are kept,
//! since the display may still show a frame of the state before the newest. The compose
//! takes one from here when it is ready or being computed, and computes it itself
//! otherwise; both give the same G-buffer (same source kind, same state).

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;

use gridlight_actors::state::{SceneState, StateVersion};

use super::{GBuffer, GBufferSource};

/// G-buffers computed ahead and kept: the newest state's and the few before it.
pub const KEEP: usize = 4;

/// The thread computing G-buffers ahead; dropping it ends the thread.
pub struct GBufferAhead {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

/// Where states are asked for, from any thread (the display's preparer).
#[derive(Clone)]
pub struct AheadHandle(Arc<Shared>);

#[derive(Default)]
struct Shared {
    slot: Mutex<Slot>,
    changed: Condvar,
}

#[derive(Default)]
struct Slot {
    /// The newest state asked for and not started yet.
    wanted: Option<Arc<SceneState>>,
    /// The version being computed now.
    computing: Option<StateVersion>,
    /// Computed ones, oldest first, at most [`KEEP`].
    ready: VecDeque<(StateVersion, Arc<GBuffer>)>,
    closed: bool,
}

impl Shared {
    // Every update is a few assignments: a panic elsewhere cannot leave the slot half
    // changed, so a poisoned lock is taken over.
    fn lock(&self) -> MutexGuard<'_, Slot> {
        self.slot.lock().unwrap_or_else(|p| p.into_inner())
    }
}

impl AheadHandle {
    /// Computes `state`'s G-buffer ahead, replacing any state asked for and not started.
    /// Never blocks for long.
    pub fn want(&self, state: Arc<SceneState>) {
        let mut slot = self.0.lock();
        let known = slot.computing == Some(state.version)
            || slot.ready.iter().any(|(v, _)| *v == state.version);
        if !known {
            slot.wanted = Some(state);
            drop(slot);
            self.0.changed.notify_all();
        }
    }
}

impl GBufferAhead {
    /// Starts the thread; it computes with `source` (its own: the composer's serves
    /// picking and must not wait behind this one).
    pub fn spawn(mut source: GBufferSource) -> std::io::Result<Self> {
        let shared = Arc::new(Shared::default());
        let worker = Arc::clone(&shared);
        let thread = std::thread::Builder::new().name("gridlight-gbuffer-ahead".into()).spawn(
            move || loop {
                let state = {
                    let slot = worker.lock();
                    let mut slot = worker
                        .changed
                        .wait_while(slot, |s| s.wanted.is_none() && !s.closed)
                        .unwrap_or_else(|p| p.into_inner());
                    if slot.closed {
                        return;
                    }
                    let Some(state) = slot.wanted.take() else { continue };
                    slot.computing = Some(state.version);
                    state
                };
                let computed = source.get(&state);
                let mut slot = worker.lock();
                slot.computing = None;
                match computed {
                    Ok(g) => {
                        slot.ready.push_back((state.version, g));
                        while slot.ready.len() > KEEP {
                            slot.ready.pop_front();
                        }
                    }
                    // The compose computes it itself and reports the error with its frame.
                    Err(e) => tracing::debug!(cause = %e, "G-buffer ahead failed"),
                }
                drop(slot);
                worker.changed.notify_all();
            },
        )?;
        Ok(Self { shared, thread: Some(thread) })
    }

    /// A handle to ask for states with.
    pub fn handle(&self) -> AheadHandle {
        AheadHandle(Arc::clone(&self.shared))
    }

    /// The G-buffer of `version` if it was computed ahead, waiting for it while it is
    /// being computed; `None` when it was not asked for (or failed): compute it then.
    /// A state asked for and not started is withdrawn, as the caller computes it now.
    pub fn take(&self, version: StateVersion) -> Option<Arc<GBuffer>> {
        let slot = self.shared.lock();
        let mut slot = self
            .shared
            .changed
            .wait_while(slot, |s| s.computing == Some(version) && !s.closed)
            .unwrap_or_else(|p| p.into_inner());
        if slot.wanted.as_ref().is_some_and(|s| s.version == version) {
            slot.wanted = None;
        }
        slot.ready.iter().rev().find(|(v, _)| *v == version).map(|(_, g)| Arc::clone(g))
    }
}

impl Drop for GBufferAhead {
    fn drop(&mut self) {
        self.shared.lock().closed = true;
        self.shared.changed.notify_all();
        if let Some(t) = self.thread.take() {
            if t.join().is_err() {
                tracing::error!("the G-buffer ahead thread panicked");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::Backend;
    use glam::Vec3;

    fn moved(state: &SceneState, version: StateVersion, x: f32) -> Arc<SceneState> {
        let mut s = state.clone();
        s.version = version;
        s.camera.position += Vec3::new(x, 0.0, 0.0);
        Arc::new(s)
    }

    #[test]
    fn a_state_asked_for_ahead_gives_the_g_buffer_the_compose_would_compute() {
        let (assets, state) = crate::render::testscenes::cornell_box(16, 12);
        let source = GBufferSource::new(Arc::clone(&assets), &state, Backend::Cpu).unwrap();
        let ahead = GBufferAhead::spawn(source).unwrap();
        let next = moved(&state, state.version + 1, 0.3);
        ahead.handle().want(Arc::clone(&next));
        let mut own = GBufferSource::new(assets, &state, Backend::Cpu).unwrap();
        let want = own.get(&next).unwrap();
        // Computed or being computed by now, or withdrawn if the thread has not started
        // it yet; `take` never answers a wrong G-buffer.
        let mut got = ahead.take(next.version);
        while got.is_none() {
            ahead.handle().want(Arc::clone(&next));
            std::thread::yield_now();
            got = ahead.take(next.version);
        }
        assert_eq!(*got.unwrap(), *want);
        assert!(ahead.take(next.version + 7).is_none(), "a state never asked for");
    }

    #[test]
    fn only_the_newest_state_asked_for_waits_and_a_few_are_kept() {
        let (assets, state) = crate::render::testscenes::cornell_box(8, 6);
        let shared = Shared::default();
        let handle = AheadHandle(Arc::new(shared));
        handle.want(moved(&state, 2, 0.1));
        handle.want(moved(&state, 3, 0.2));
        let slot = handle.0.lock();
        assert_eq!(slot.wanted.as_ref().map(|s| s.version), Some(3), "2 was superseded");
        drop(slot);
        let g = GBufferSource::new(assets, &state, Backend::Cpu).unwrap().get(&state).unwrap();
        handle.0.lock().wanted = None; // as the thread takes it
        handle.0.lock().ready.push_back((3, g));
        handle.want(moved(&state, 3, 0.2));
        assert!(handle.0.lock().wanted.is_none(), "a state computed already is not asked again");
    }
}
