//! The integration tests, compiled into one binary (one module per stage).

mod cli;
mod collapse;
mod detect;
mod process;
mod render;
mod source;
mod source_tiff;
