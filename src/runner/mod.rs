//! Running cells in isolation: the worker (`rtprobe __worker`), the supervisor that owns
//! deadlines and kills, their line protocol, the phases a worker reports, and the supervisor's
//! own fault injection for its tests.
pub mod groups;
pub mod misbehave;
pub mod process;
pub mod protocol;
pub mod supervisor;
pub mod worker;
