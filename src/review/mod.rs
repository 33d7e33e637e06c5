//! `dropscope review`: look at every frame of a drop with what the
//! pipeline used there, and record what a person decides about it
//! ([`crate::dataset::decisions`], `review.csv`).
//!
//! | file | what |
//! | --- | --- |
//! | [`server`] | the page's small HTTP/1.1 server on 127.0.0.1: a per-session token, routes, a pool of workers, Ctrl-C |
//! | [`http`] | one request read and one response written, with the limits and checks every request passes |
//! | [`frames`] | one frame drawn as PNG with its edge points (used and rejected), circle, surface line and predicted window |
//! | [`data`] | what the page shows of a folder: drops.csv, a run's track CSV, as JSON |
//! | `page.html`, `page.js`, `page.css` | the page, embedded in the binary (no network) |

pub mod data;
pub mod frames;
pub mod http;
pub mod server;
