//! The table of connected workers the window's status panel lists: name, host, cores,
//! jobs per second, jobs done, late results, mean render time per job, last seen, and
//! whether (and why) a worker is paused. Connection actors write their own row (join, each
//! accepted result, pause, resume, end), the assembler counts late results; readers get a
//! snapshot. Rows exist only for live connections, so the table is
//! bounded by the connection cap. How many workers are live or paused is counted from the
//! rows ([`WorkerTable::counts`]), never kept beside them.

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::wire::protocol::ConnId;
use crate::wire::protocol::PauseReason;

/// Window over which a worker's job rate is measured.
pub const RATE_WINDOW: Duration = Duration::from_secs(2);

/// One connected worker as the status panel shows it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WorkerInfo {
    pub id: ConnId,
    pub name: String,
    pub cores: u32,
    /// Results that came back over the last [`RATE_WINDOW`], per second.
    pub jobs_per_second: f64,
    /// Results since it joined.
    pub jobs: u64,
    /// Its results that came back after their frame was shown (dropped, never used).
    pub late: u64,
    /// Mean render time per job as the worker reports it (0 before its first result).
    pub mean_job_time: Duration,
    /// The host it connects from (IP address).
    pub host: String,
    /// Time since its last message.
    pub last_seen: Duration,
    /// Why it is paused (its desk's owner is active); `None` while it takes jobs.
    pub paused: Option<PauseReason>,
}

/// How many connected workers take jobs and how many are paused, as the table has them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WorkerCounts {
    /// Connected, past the handshake, taking jobs.
    pub live: u64,
    /// Connected but paused (their desks' owners are active).
    pub paused: u64,
}

/// A paused worker as the per-frame statistics name it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PausedWorker {
    pub name: String,
    /// [`PauseReason::kind`].
    pub kind: &'static str,
    /// The reason, for a human.
    pub reason: String,
}

#[derive(Debug)]
struct Row {
    name: String,
    cores: u32,
    jobs: u64,
    /// Jobs counted at the start of the current rate window, and when it began.
    window_jobs: u64,
    window_start: Instant,
    /// Rate over the last complete window.
    rate: f64,
    last_seen: Instant,
    paused: Option<PauseReason>,
    late: u64,
    /// Sum and count of reported render times.
    render_us: u64,
    timed_jobs: u64,
    host: String,
}

/// Live workers by connection.
#[derive(Debug, Default)]
pub struct WorkerTable {
    rows: Mutex<BTreeMap<ConnId, Row>>,
}

impl WorkerTable {
    /// A worker passed the handshake.
    pub fn joined(&self, id: ConnId, name: &str, cores: u32) {
        let now = Instant::now();
        let row = Row {
            name: name.to_string(),
            cores,
            jobs: 0,
            window_jobs: 0,
            window_start: now,
            rate: 0.0,
            last_seen: now,
            paused: None,
            late: 0,
            render_us: 0,
            timed_jobs: 0,
            host: String::new(),
        };
        self.lock().insert(id, row);
    }

    /// The worker connects from `host`.
    pub fn located(&self, id: ConnId, host: &str) {
        if let Some(row) = self.lock().get_mut(&id) {
            row.host = host.to_owned();
        }
    }

    /// One of its results took `render_us` microseconds to render.
    pub fn timed(&self, id: ConnId, render_us: u64) {
        if let Some(row) = self.lock().get_mut(&id) {
            row.render_us = row.render_us.saturating_add(render_us);
            row.timed_jobs += 1;
        }
    }

    /// One of its results came back too late for its frame.
    pub fn late(&self, id: ConnId) {
        if let Some(row) = self.lock().get_mut(&id) {
            row.late += 1;
        }
    }

    /// A message came from the worker; `results` of them were accepted results.
    pub fn heard(&self, id: ConnId, results: u64) {
        let now = Instant::now();
        if let Some(row) = self.lock().get_mut(&id) {
            row.last_seen = now;
            row.jobs += results;
            let span = now - row.window_start;
            if span >= RATE_WINDOW {
                row.rate = (row.jobs - row.window_jobs) as f64 / span.as_secs_f64();
                row.window_jobs = row.jobs;
                row.window_start = now;
            }
        }
    }

    /// The worker paused (or its reason changed).
    pub fn paused(&self, id: ConnId, reason: PauseReason) {
        if let Some(row) = self.lock().get_mut(&id) {
            row.paused = Some(reason);
        }
    }

    /// The worker takes jobs again.
    pub fn resumed(&self, id: ConnId) {
        if let Some(row) = self.lock().get_mut(&id) {
            row.paused = None;
        }
    }

    /// Live and paused workers now: counted from the rows, never kept beside them.
    pub fn counts(&self) -> WorkerCounts {
        let rows = self.lock();
        let paused = rows.values().filter(|r| r.paused.is_some()).count() as u64;
        WorkerCounts { live: rows.len() as u64 - paused, paused }
    }

    /// The paused workers, by connection id.
    pub fn paused_list(&self) -> Vec<PausedWorker> {
        self.lock()
            .values()
            .filter_map(|r| {
                let reason = r.paused.as_ref()?;
                Some(PausedWorker {
                    name: r.name.clone(),
                    kind: reason.kind(),
                    reason: reason.to_string(),
                })
            })
            .collect()
    }

    /// The connection ended.
    pub fn left(&self, id: ConnId) {
        self.lock().remove(&id);
    }

    /// A snapshot, by connection id.
    pub fn list(&self) -> Vec<WorkerInfo> {
        let now = Instant::now();
        self.lock()
            .iter()
            .map(|(&id, r)| {
                // A worker silent for a whole window has a rate of zero, not its old one.
                let silent = now - r.last_seen >= RATE_WINDOW;
                WorkerInfo {
                    id,
                    name: r.name.clone(),
                    cores: r.cores,
                    jobs_per_second: if silent { 0.0 } else { r.rate },
                    jobs: r.jobs,
                    late: r.late,
                    mean_job_time: Duration::from_micros(
                        r.render_us.checked_div(r.timed_jobs).unwrap_or(0),
                    ),
                    host: r.host.clone(),
                    last_seen: now - r.last_seen,
                    paused: r.paused.clone(),
                }
            })
            .collect()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, BTreeMap<ConnId, Row>> {
        self.rows.lock().unwrap_or_else(|p| p.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_follow_joins_results_and_departures() {
        let t = WorkerTable::default();
        t.joined(3, "a", 4);
        t.joined(1, "b", 1);
        t.heard(3, 2);
        t.heard(9, 5); // unknown connection: ignored
        t.located(3, "10.0.0.7");
        t.timed(3, 1000);
        t.timed(3, 3000);
        t.late(3);
        t.late(9);
        let list = t.list();
        assert_eq!(list.iter().map(|w| w.id).collect::<Vec<_>>(), vec![1, 3]);
        assert_eq!((list[1].name.as_str(), list[1].cores, list[1].jobs), ("a", 4, 2));
        assert_eq!((list[1].host.as_str(), list[1].late), ("10.0.0.7", 1));
        assert_eq!(list[1].mean_job_time, Duration::from_millis(2));
        assert_eq!((list[0].late, list[0].mean_job_time), (0, Duration::ZERO));
        t.left(3);
        assert_eq!(t.list().len(), 1);
    }

    #[test]
    fn a_paused_worker_stays_listed_with_its_reason_until_it_resumes() {
        let t = WorkerTable::default();
        t.joined(1, "desk", 2);
        t.joined(2, "lab", 2);
        t.paused(1, PauseReason::OwnerInput { seconds_ago: 3.0 });
        let list = t.list();
        assert_eq!(list.len(), 2, "paused workers are listed");
        assert_eq!(list[0].paused, Some(PauseReason::OwnerInput { seconds_ago: 3.0 }));
        assert_eq!(list[1].paused, None);
        assert_eq!(t.counts(), WorkerCounts { live: 1, paused: 1 });
        let paused = t.paused_list();
        assert_eq!(paused.len(), 1);
        assert_eq!((paused[0].name.as_str(), paused[0].kind), ("desk", "owner_input"));
        assert!(paused[0].reason.contains("keyboard or mouse"), "{}", paused[0].reason);
        t.resumed(1);
        assert_eq!(t.counts(), WorkerCounts { live: 2, paused: 0 });
        t.left(2);
        assert_eq!(t.counts(), WorkerCounts { live: 1, paused: 0 });
        assert!(t.paused_list().is_empty());
        assert_eq!(t.list()[0].paused, None);
    }

    #[test]
    fn the_rate_is_measured_over_a_window() {
        let t = WorkerTable::default();
        t.joined(1, "a", 1);
        {
            let mut rows = t.lock();
            let row = rows.get_mut(&1).unwrap();
            row.window_start -= RATE_WINDOW * 2; // as if it joined 4 s ago
        }
        t.heard(1, 8);
        let rate = t.list()[0].jobs_per_second;
        assert!((1.9..=2.1).contains(&rate), "8 jobs over ~4 s, got {rate}");
    }
}
