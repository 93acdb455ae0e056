//! Jobs between the connections and the scheduler: credits in, jobs out, and what became
//! of the jobs a worker held.

use std::time::Instant;

use actix::prelude::*;

use crate::shared::job::Job;
use crate::wire::protocol::{ConnId, FrameNo};

/// A connection's worker can take `credits` more jobs; send them to `jobs_to`.
#[derive(Message)]
#[rtype(result = "()")]
pub struct WorkerReady {
    pub conn: ConnId,
    pub credits: u32,
    pub jobs_to: Recipient<JobsAssigned>,
}

/// A connection ended or its worker paused; its unserved credits are void and the jobs
/// it held are lost (taken out of the record of held jobs, never redone).
#[derive(Message)]
#[rtype(result = "()")]
pub struct WorkerLeft {
    pub conn: ConnId,
    /// The frame of each job it held: other sets of those frames make up their quota.
    pub lost: Vec<FrameNo>,
}

/// A connection received its worker's result for a job of `frame` handed out at
/// `handed_at` (in time or not), rendered in `render_us` by the worker's account: the
/// worker's job time and the grid's speed are measured from these.
#[derive(Message, Clone, Copy)]
#[rtype(result = "()")]
pub struct JobAnswered {
    pub conn: ConnId,
    pub frame: FrameNo,
    pub handed_at: Instant,
    pub render_us: u64,
}

/// To a connection: jobs handed to it.
#[derive(Message)]
#[rtype(result = "()")]
pub struct JobsAssigned(pub Vec<Job>);
