//! Running cells in isolation: the worker (`rtprobe __worker`), the supervisor that owns
//! deadlines and kills, their line protocol, the phases a worker reports, the supervisor's own
//! fault injection for its tests, and the oracle trait the rounds above run cells through.
pub mod groups;
pub mod misbehave;
pub mod oracle;
pub mod process;
pub mod protocol;
pub mod supervisor;
pub mod worker;
