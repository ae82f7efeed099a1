//! Fleets and CI: expectations a run is held to (`baseline`, with deqp-runner's `test,Status`
//! form in `deqp`), deterministic shards for a CI system's parallel jobs (`shard`), joining their
//! reports (`merge`), what changed between two runs (`diff`), and deqp-runner's other files
//! (`deqp_files`: skips and flakes lists, results.csv, failures.csv). rtprobe shards and merges;
//! the CI system schedules the machines.
pub mod baseline;
pub mod deqp;
pub mod deqp_files;
pub mod diff;
pub mod merge;
pub mod shader_baseline;
pub mod shard;
