//! Running cells in isolation: the worker (`rtprobe __worker`), the supervisor that owns
//! deadlines and kills, and their line protocol.
pub mod protocol;
pub mod supervisor;
pub mod worker;
