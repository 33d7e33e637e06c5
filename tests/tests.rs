//! The integration tests, compiled into one binary (one module per stage).

mod cli;
mod collapse;
mod detect;
mod process;
mod render;
mod report;
mod run;
mod source;
mod source_tiff;
