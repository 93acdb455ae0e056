//! Jobs between the connections and the scheduler: credits in, jobs out, and what became
//! of the jobs a worker held.

use actix::prelude::*;

use crate::shared::job::Job;
use crate::wire::protocol::{ConnId, FrameNo, SetNo};

/// A connection's worker can take `credits` more jobs; send them to `jobs_to`.
#[derive(Message)]
#[rtype(result = "()")]
pub struct WorkerReady {
    pub conn: ConnId,
    pub credits: u32,
    pub jobs_to: Recipient<JobsAssigned>,
}

/// A connection ended or its worker paused; its unserved credits are void (its held
/// jobs are not redone).
#[derive(Message)]
#[rtype(result = "()")]
pub struct WorkerLeft {
    pub conn: ConnId,
}

/// A connection received its worker's result for `(frame, set)` (in time or not): the
/// worker's job time is measured from these.
#[derive(Message, Clone, Copy)]
#[rtype(result = "()")]
pub struct JobAnswered {
    pub conn: ConnId,
    pub frame: FrameNo,
    pub set: SetNo,
}

/// To a connection: jobs handed to it.
#[derive(Message)]
#[rtype(result = "()")]
pub struct JobsAssigned(pub Vec<Job>);
