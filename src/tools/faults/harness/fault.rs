//! The faults a harness can inject (issue 6), each undone or outlived by the grid.

use std::time::{Duration, Instant};

use gridlight_actors::master::ActorKind;

use super::workers::signal;
use super::{Harness, HarnessError};
use crate::tools::faults::invariants::lock;
use crate::tools::faults::proxy::LinkMode;

/// One fault of issue 6's list, as the soak and the tests inject it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fault {
    /// SIGKILL the `i`-th worker process (modulo the count).
    KillWorker(usize),
    /// SIGSTOP the `i`-th running worker (thawed by [`Harness::undo`]).
    FreezeWorker(usize),
    /// Start one more worker process.
    SpawnWorker,
    /// A panic inside a core actor of the master; its supervisor restarts it.
    PanicActor(ActorKind),
    /// End the `i`-th connection actor abruptly.
    KillConnection(usize),
    /// A panic inside the `i`-th connection actor.
    PanicConnection(usize),
    /// Set the proxy's mode for the proxied workers (undone by [`Harness::undo`]).
    Link(LinkMode),
    /// Stop the master and start a new one on the same address.
    RestartMaster,
}

impl Fault {
    /// One fault of every kind, in an order that keeps the grid alive between them.
    pub fn every_kind() -> Vec<Fault> {
        let mut all = vec![Fault::SpawnWorker, Fault::KillWorker(0), Fault::FreezeWorker(0)];
        all.extend(
            [
                ActorKind::Scheduler,
                ActorKind::Assembler,
                ActorKind::Presenter,
                ActorKind::SceneHolder,
            ]
            .map(Fault::PanicActor),
        );
        all.extend([Fault::KillConnection(0), Fault::PanicConnection(1)]);
        all.extend(
            [
                LinkMode::Delay(Duration::from_millis(100)),
                LinkMode::Drop,
                LinkMode::Truncate,
                LinkMode::Corrupt,
                LinkMode::Stall,
                LinkMode::Cut,
            ]
            .map(Fault::Link),
        );
        all.push(Fault::RestartMaster);
        all
    }
}

impl Harness {
    /// SIGKILLs worker `i` (modulo the count); false when there is none.
    pub fn kill_worker(&mut self, i: usize) -> bool {
        if self.workers.is_empty() {
            return false;
        }
        let mut w = self.workers.remove(i % self.workers.len());
        let _ = w.child.kill();
        let _ = w.child.wait();
        self.fault("kill_worker");
        let how = if w.proxied { "proxied" } else { "direct" };
        lock(&self.checker).event(Instant::now(), format!("(the killed worker was {how})"));
        self.note_live();
        true
    }

    /// SIGSTOPs the `i`-th running worker; false when none runs.
    pub fn freeze_worker(&mut self, i: usize) -> bool {
        let running: Vec<usize> =
            (0..self.workers.len()).filter(|&j| !self.workers[j].frozen).collect();
        if running.is_empty() {
            return false;
        }
        let w = &mut self.workers[running[i % running.len()]];
        signal(&w.child, libc::SIGSTOP);
        w.frozen = true;
        self.fault("freeze_worker");
        self.note_live();
        true
    }

    /// SIGCONTs every frozen worker.
    pub fn thaw_all(&mut self) {
        for w in self.workers.iter_mut().filter(|w| w.frozen) {
            signal(&w.child, libc::SIGCONT);
            w.frozen = false;
        }
        self.note_live();
    }

    /// Starts or kills workers until `n` are live (the resource curve).
    pub fn set_live(&mut self, n: usize) -> Result<(), HarnessError> {
        self.thaw_all();
        while self.workers.len() > n {
            self.kill_worker(self.workers.len() - 1);
        }
        while self.workers.len() < n {
            self.spawn_worker()?;
        }
        Ok(())
    }

    /// Makes a core actor of the master panic (its supervisor restarts it).
    pub fn panic_actor(&mut self, kind: ActorKind) {
        if let Some(m) = &self.master {
            m.inject_panic(kind);
            self.fault(&format!("panic_{}", kind.name().replace('-', "_")));
        }
    }

    /// Kills (or makes panic) the `i`-th live connection actor; false when none.
    pub fn fault_connection(&mut self, i: usize, panic: bool) -> bool {
        let Some(m) = &self.master else { return false };
        let Ok(ids) = m.connections() else { return false };
        if ids.is_empty() {
            return false;
        }
        let id = ids[i % ids.len()];
        let done = if panic { m.panic_connection(id) } else { m.kill_connection(id) };
        if matches!(done, Ok(true)) {
            self.fault(if panic { "panic_connection" } else { "kill_connection" });
        }
        matches!(done, Ok(true))
    }

    /// Sets the proxy's mode (link faults for the proxied workers).
    pub fn link_fault(&mut self, mode: LinkMode) {
        let Some(p) = &self.proxy else { return };
        if mode == LinkMode::Cut {
            p.cut_all();
        } else {
            p.set_mode(mode);
        }
        if mode != LinkMode::Pass {
            self.fault(&format!("link_{}", mode.name()));
        }
        self.note_live();
    }

    /// Stops the master and starts a new one on the same address; workers must come
    /// back by themselves.
    pub fn restart_master(&mut self) -> Result<(), HarnessError> {
        lock(&self.checker).note_live(0, Instant::now());
        if let Some(m) = self.master.take() {
            self.add_up(m.counters());
            if let Err(e) = m.stop() {
                lock(&self.checker).violate(format!("the master failed to stop: {e}"));
            }
        }
        self.fault("restart_master");
        self.report.master_restarts += 1;
        self.start_master()?;
        lock(&self.checker).event(Instant::now(), "the new master listens".into());
        self.note_live();
        Ok(())
    }

    /// Injects one fault; true when it lasts until [`Harness::undo`] (a link fault, a
    /// freeze). A fault with nothing to act on (no worker, no connection) is not counted.
    pub fn inject(&mut self, fault: Fault) -> Result<bool, HarnessError> {
        Ok(match fault {
            Fault::KillWorker(i) => {
                self.kill_worker(i);
                false
            }
            Fault::FreezeWorker(i) => self.freeze_worker(i),
            Fault::SpawnWorker => {
                self.spawn_worker()?;
                self.fault("spawn_worker");
                false
            }
            Fault::PanicActor(kind) => {
                self.panic_actor(kind);
                false
            }
            Fault::KillConnection(i) => {
                self.fault_connection(i, false);
                false
            }
            Fault::PanicConnection(i) => {
                self.fault_connection(i, true);
                false
            }
            Fault::Link(mode) => {
                self.link_fault(mode);
                mode != LinkMode::Pass
            }
            Fault::RestartMaster => {
                self.restart_master()?;
                false
            }
        })
    }

    /// Ends lasting faults: the link passes again and frozen workers are thawed.
    pub fn undo(&mut self) {
        lock(&self.checker).event(Instant::now(), "undo (link passes, workers thawed)".into());
        self.link_fault(LinkMode::Pass);
        self.thaw_all();
    }

    fn fault(&mut self, kind: &str) {
        *self.report.faults.entry(kind.to_owned()).or_default() += 1;
        lock(&self.checker).event(Instant::now(), kind.to_owned());
    }
}
