//! Running cells in isolation: the worker (`rtprobe __worker`), the supervisor that owns
//! deadlines and kills, their line protocol, the phases a worker reports, the supervisor's own
//! fault injection for its tests, and the oracle trait the rounds above run cells through. The
//! supervisor's parts: a worker's lines as a pure state machine (`machine`) emitting the events
//! everything above records (`event`), which worker runs which cells (`schedule`), the faults
//! injected into each attempt (`injection`) and the processes themselves (`process`).
pub mod event;
pub mod groups;
mod held;
mod injection;
mod machine;
pub mod misbehave;
pub mod oracle;
mod overlap;
pub mod process;
pub mod protocol;
mod schedule;
pub mod self_exe;
pub mod supervisor;
pub mod worker;
mod worker_io;
