//! The integration tests, compiled into one binary (one module per stage).

mod cli;
mod detect;
mod render;
