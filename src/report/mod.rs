//! Reports: writing them atomically (and, with the runner, their schema, reading, JUnit and Markdown).
pub mod atomic;
pub mod time;

pub use atomic::write_atomic;
