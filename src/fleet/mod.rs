//! Fleets and CI: expectations a run is held to (`baseline`), deterministic shards for a CI
//! system's parallel jobs (`shard`), joining their reports (`merge`), what changed between two
//! runs (`diff`), and deqp-runner's files (`deqp`: skips and flakes lists, results.csv,
//! failures.csv). rtprobe shards and merges; the CI system schedules the machines.
pub mod baseline;
pub mod deqp;
pub mod diff;
pub mod merge;
pub mod shard;
