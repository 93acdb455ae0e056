//! Recording the window's edits with the time each was made, for saving as an
//! interaction script that `--script` replays.

use std::time::{Duration, Instant};

use super::edits::WindowEdit;

/// Edits made while recording, each with its time since recording started.
#[derive(Clone, Debug, Default)]
pub struct Recorder {
    started: Option<Instant>,
    entries: Vec<(Duration, WindowEdit)>,
}

impl Recorder {
    /// Starts (true) or pauses (false) recording; times continue from the first start.
    pub fn set_recording(&mut self, on: bool, now: Instant) {
        match (on, self.started) {
            (true, None) => {
                self.started = Some(now - self.entries.last().map_or(Duration::ZERO, |e| e.0))
            }
            (false, Some(_)) => self.started = None,
            _ => {}
        }
    }

    /// True while recording.
    pub fn is_recording(&self) -> bool {
        self.started.is_some()
    }

    /// Records `edit` made at `now`, if recording.
    pub fn record(&mut self, edit: &WindowEdit, now: Instant) {
        if let Some(start) = self.started {
            self.entries.push((now.saturating_duration_since(start), edit.clone()));
        }
    }

    /// The recorded edits in order.
    pub fn entries(&self) -> &[(Duration, WindowEdit)] {
        &self.entries
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridlight_actors::state::Environment;

    #[test]
    fn records_only_while_on_with_times_from_the_start() {
        let t0 = Instant::now();
        let edit = WindowEdit::Environment(None);
        let mut r = Recorder::default();
        r.record(&edit, t0);
        assert!(r.entries().is_empty(), "not recording yet");
        r.set_recording(true, t0);
        r.record(&edit, t0 + Duration::from_millis(250));
        r.set_recording(false, t0 + Duration::from_secs(1));
        r.record(&edit, t0 + Duration::from_secs(2));
        let env = WindowEdit::Environment(Some(Environment {
            map: None,
            color: glam::Vec3::ONE,
            intensity: 1.0,
            rotation_deg: 0.0,
        }));
        // Resuming continues after the last recorded edit, without the pause.
        r.set_recording(true, t0 + Duration::from_secs(5));
        r.record(&env, t0 + Duration::from_millis(5100));
        let times: Vec<_> = r.entries().iter().map(|e| e.0).collect();
        assert_eq!(times, [Duration::from_millis(250), Duration::from_millis(350)]);
        assert_eq!(r.entries()[1].1, env);
    }
}
