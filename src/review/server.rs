//! The review page's server: HTTP/1.1 on `127.0.0.1` only, on a free port
//! (or the one asked for), a few worker threads, until Ctrl-C.
//!
//! Every request must carry the session's token (`?token=…`, 128 random
//! bits made at start and printed with the address): another web page the
//! browser has open cannot guess it, so it can neither read the folder nor
//! post a decision. A request whose `Host` is not this server's address
//! (a DNS-rebinding page), or whose `Origin` is another site's, is refused
//! too, and a decision must come as JSON from the page's own origin. Every
//! parameter is checked against what the folder holds (a run of its
//! drops.csv, a frame of that run, a view by name) before anything is read
//! or written: a bad request gets a 4xx with a sentence saying what was
//! wrong, and changes nothing.
//!
//! | request | answer |
//! | --- | --- |
//! | `GET /` | the page (`page.html`, with `page.js` and `page.css`) |
//! | `GET /api/drops` | the drop list ([`super::data::drops_json`]) |
//! | `GET /api/run?run=R` | one run ([`super::data::RunData`]) |
//! | `GET /api/frame?run=R&frame=N&view=sphere\|contact\|frame` | the frame as PNG ([`super::frames`]); header `X-Dropscope-View: x0 z0 zoom` |
//! | `POST /api/decide` | `{run, decision, frames?, value?, reason}`: saved at once in review.csv |
//! | `POST /api/withdraw` | `{run, decision, frames?}`: removed from review.csv |

use std::io::{BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};

use serde::Deserialize;
use serde_json::json;

use super::data::{drops_json, frames_in, impact_column, RunData};
use super::frames::{RunView, View};
use super::http::{read_request, same_secret, write_response, ReadError, Request, Response};
use crate::config::PipelineConfig;
use crate::dataset::decisions::{Decision, Decisions, Frames, Kind};
use crate::dataset::{DropRecord, TrackRow};

const PAGE_HTML: &str = include_str!("page.html");
const PAGE_JS: &str = include_str!("page.js");
const PAGE_CSS: &str = include_str!("page.css");

/// Runs held open for drawing frames (each its source, background and track).
const RUNS_OPEN: usize = 4;
/// Worker threads answering requests.
pub const WORKERS: usize = 4;
/// How long a connection may take to send its request, or to take its answer.
const IO_TIMEOUT: Duration = Duration::from_secs(20);

/// What to serve.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// The output folder (its drops.csv, tracks/ and the runs' inputs).
    pub out: PathBuf,
    /// Where decisions are saved, below `out`
    /// ([`crate::dataset::decisions::review_rel`]).
    pub review_rel: String,
    /// The configuration: the detection settings the frames are drawn with,
    /// the frame rate for inputs that carry none.
    pub cfg: PipelineConfig,
    /// The port on 127.0.0.1; 0 for any free one.
    pub port: u16,
    /// The manifest's `number_digits` of the runs that give one, so that
    /// a folder's frames are numbered as the job numbered them.
    pub number_digits: std::collections::BTreeMap<String, usize>,
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The port could not be listened on (in use, or not allowed).
    #[error("cannot listen on 127.0.0.1:{port}: {source}")]
    Bind {
        /// The port asked for.
        port: u16,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Another I/O error of the listening socket.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

/// A server bound to its port, not yet serving.
pub struct Server {
    listener: TcpListener,
    state: Arc<State>,
}

/// What every worker shares.
struct State {
    out: PathBuf,
    /// The decisions file below `out`, written only through
    /// [`crate::util::out_folder`].
    review_rel: String,
    cfg: PipelineConfig,
    number_digits: std::collections::BTreeMap<String, usize>,
    token: String,
    port: u16,
    /// drops.csv as last read, with the stamp of the file read.
    drops: Mutex<Option<(Stamp, Arc<Vec<DropRecord>>)>>,
    /// Runs opened for drawing, the most recent last.
    runs: Mutex<Vec<OpenRun>>,
    /// One change of review.csv at a time.
    writing: Mutex<()>,
}

/// A file's modification time and length: when either changes, what was
/// read from it is read again (a job rewrote the folder).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Stamp(Option<SystemTime>, u64);

fn stamp(path: &Path) -> Stamp {
    std::fs::metadata(path).map_or(Stamp(None, 0), |m| Stamp(m.modified().ok(), m.len()))
}

/// A run held open: its name, the stamp of its track CSV when opened, it.
type OpenRun = (String, Stamp, Arc<Mutex<Opened>>);

/// A run opened: its frames' source, its track CSV.
struct Opened {
    view: Result<RunView, String>,
    rows: Vec<TrackRow>,
    /// Every camera image number (the source's, else the track's).
    frames: Vec<i64>,
}

impl Server {
    /// Listen on 127.0.0.1 at `opts.port` (0: a free port), with a new token.
    pub fn bind(opts: ServeOptions) -> Result<Server, ServeError> {
        let listener =
            TcpListener::bind(("127.0.0.1", opts.port)).map_err(|source| ServeError::Bind {
                port: opts.port,
                source,
            })?;
        let port = listener.local_addr()?.port();
        let state = State {
            out: opts.out,
            review_rel: opts.review_rel,
            cfg: opts.cfg,
            number_digits: opts.number_digits,
            token: new_token(),
            port,
            drops: Mutex::new(None),
            runs: Mutex::new(Vec::new()),
            writing: Mutex::new(()),
        };
        Ok(Server {
            listener,
            state: Arc::new(state),
        })
    }

    /// The port listened on.
    pub fn port(&self) -> u16 {
        self.state.port
    }

    /// The session's token.
    pub fn token(&self) -> &str {
        &self.state.token
    }

    /// The page's address, token and all.
    pub fn url(&self) -> String {
        format!(
            "http://127.0.0.1:{}/?token={}",
            self.state.port, self.state.token
        )
    }

    /// Answer requests on [`WORKERS`] threads until `stop` is set; then
    /// finish the requests taken and return.
    pub fn serve(self, stop: &AtomicBool) -> Result<(), ServeError> {
        self.listener.set_nonblocking(true)?;
        let (tx, rx) = std::sync::mpsc::channel::<TcpStream>();
        let rx = Arc::new(Mutex::new(rx));
        let workers: Vec<_> = (0..WORKERS)
            .map(|_| {
                let (rx, state) = (Arc::clone(&rx), Arc::clone(&self.state));
                std::thread::spawn(move || loop {
                    let next = rx.lock().map(|r| r.recv());
                    match next {
                        Ok(Ok(stream)) => answer(&state, stream),
                        _ => break,
                    }
                })
            })
            .collect();
        while !stop.load(Ordering::SeqCst) {
            match self.listener.accept() {
                Ok((stream, _)) => {
                    if stream.set_nonblocking(false).is_ok() {
                        let _ = tx.send(stream);
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                // A connection reset before it was taken, out of file
                // handles for a moment: the next one may do.
                Err(_) => std::thread::sleep(Duration::from_millis(20)),
            }
        }
        drop(tx);
        for w in workers {
            let _ = w.join();
        }
        Ok(())
    }
}

/// 128 random bits from the operating system, as 32 hex digits.
fn new_token() -> String {
    use rand::RngCore;
    let mut bytes = [0u8; 16];
    rand::rngs::OsRng.fill_bytes(&mut bytes);
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Set by Ctrl-C (SIGINT) or SIGTERM once [`stop_on_signals`] is called.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

/// A flag Ctrl-C (SIGINT) and SIGTERM set, for [`Server::serve`].
pub fn stop_on_signals() -> &'static AtomicBool {
    let handler = on_signal as extern "C" fn(libc::c_int);
    // SAFETY: the handler only stores to an atomic, which is
    // async-signal-safe; installing it changes nothing else.
    unsafe {
        libc::signal(libc::SIGINT, handler as libc::sighandler_t);
        libc::signal(libc::SIGTERM, handler as libc::sighandler_t);
    }
    &STOP
}

/// Read one request from `stream`, answer it, close.
fn answer(state: &State, stream: TcpStream) {
    let _ = stream.set_read_timeout(Some(IO_TIMEOUT));
    let _ = stream.set_write_timeout(Some(IO_TIMEOUT));
    let Ok(mut out) = stream.try_clone() else {
        return;
    };
    let mut input = BufReader::new(stream);
    let response = match read_request(&mut input) {
        Ok(req) => std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| handle(state, &req)))
            .unwrap_or_else(|_| {
                Response::error(
                    500,
                    "internal error (a bug in dropscope review; please report it)",
                )
            }),
        Err(ReadError::Refused(r)) => r,
        Err(ReadError::Closed) => return,
    };
    let _ = write_response(&mut out, &response);
    let _ = out.flush();
}

/// The answer to `req`: the checks every request passes, then its route.
fn handle(state: &State, req: &Request) -> Response {
    if let Err(r) = check_origin(state, req) {
        return r;
    }
    match req.param("token") {
        None => {
            return Response::error(
                403,
                "no token: open the address `dropscope review` printed, ?token=… and all",
            )
        }
        Some(t)
            if !same_secret(t, &state.token)
                || req.query.iter().filter(|(k, _)| k == "token").count() != 1 =>
        {
            return Response::error(
                403,
                "wrong token: this page is not the one `dropscope review` is serving now \
                 (open the address it printed last)",
            )
        }
        Some(_) => {}
    }
    let routes: [(&str, &str, &[&str]); 8] = [
        ("GET", "/", &[]),
        ("GET", "/page.js", &[]),
        ("GET", "/page.css", &[]),
        ("GET", "/api/drops", &[]),
        ("GET", "/api/run", &["run"]),
        ("GET", "/api/frame", &["run", "frame", "view"]),
        ("POST", "/api/decide", &[]),
        ("POST", "/api/withdraw", &[]),
    ];
    let Some(&(method, _, params)) = routes.iter().find(|(_, p, _)| *p == req.path) else {
        return Response::error(404, format!("no page `{}` here", one_line(&req.path)));
    };
    if req.method != method {
        return Response::error(405, format!("{} takes {method} only", req.path))
            .with("Allow", method.to_string());
    }
    for (k, _) in &req.query {
        if k != "token" && !params.contains(&k.as_str()) {
            return Response::error(400, format!("unknown parameter `{}`", one_line(k)));
        }
    }
    if method == "POST" {
        if let Err(r) = check_post(req) {
            return r;
        }
    }
    let result = match req.path.as_str() {
        "/" => Ok(Response::new(
            200,
            "text/html; charset=utf-8",
            PAGE_HTML.replace("{{TOKEN}}", &state.token).into_bytes(),
        )),
        "/page.js" => Ok(Response::new(
            200,
            "text/javascript; charset=utf-8",
            PAGE_JS.as_bytes().to_vec(),
        )),
        "/page.css" => Ok(Response::new(
            200,
            "text/css; charset=utf-8",
            PAGE_CSS.as_bytes().to_vec(),
        )),
        "/api/drops" => api_drops(state),
        "/api/run" => api_run(state, req),
        "/api/frame" => api_frame(state, req),
        "/api/decide" => api_decide(state, req),
        _ => api_withdraw(state, req),
    };
    result.unwrap_or_else(|r| r)
}

/// `s` on one line and short, for a message: control and format
/// characters shown as `\u{…}` ([`crate::util::text::one_line`]).
fn one_line(s: &str) -> String {
    let flat = crate::util::text::one_line(s);
    match flat.char_indices().nth(80) {
        Some((i, _)) => format!("{}…", &flat[..i]),
        None => flat.into_owned(),
    }
}

/// The request is addressed to this server (`Host`) from its own page or
/// from no page (`Origin`, `Sec-Fetch-Site`).
fn check_origin(state: &State, req: &Request) -> Result<(), Response> {
    let ours = [
        format!("127.0.0.1:{}", state.port),
        format!("localhost:{}", state.port),
    ];
    match (req.header("host"), req.header_count("host")) {
        (Some(h), 1) if ours.iter().any(|o| o.eq_ignore_ascii_case(h)) => {}
        (None, _) => return Err(Response::error(400, "no Host header")),
        (Some(h), _) => {
            return Err(Response::error(
                403,
                format!(
                    "Host `{}` is not this server ({}): the review page answers only to its own \
                     address",
                    one_line(h),
                    ours[0]
                ),
            ))
        }
    }
    if let Some(o) = req.header("origin") {
        if !ours
            .iter()
            .any(|a| o.eq_ignore_ascii_case(&format!("http://{a}")))
        {
            return Err(Response::error(
                403,
                format!(
                    "a request from another origin (`{}`): only the review page itself may ask",
                    one_line(o)
                ),
            ));
        }
    }
    if let Some(site) = req.header("sec-fetch-site") {
        if site != "same-origin" && site != "none" {
            return Err(Response::error(
                403,
                format!(
                    "a request from another site (Sec-Fetch-Site: {})",
                    one_line(site)
                ),
            ));
        }
    }
    Ok(())
}

/// A decision comes as JSON from the page's origin.
fn check_post(req: &Request) -> Result<(), Response> {
    if req.header("origin").is_none() {
        return Err(Response::error(
            403,
            "a decision must come from the review page (the request has no Origin)",
        ));
    }
    let json = req.header("content-type").is_some_and(|t| {
        t.split(';')
            .next()
            .is_some_and(|m| m.trim() == "application/json")
    });
    if !json {
        return Err(Response::error(
            415,
            "a decision is sent as application/json",
        ));
    }
    Ok(())
}

impl State {
    fn drops_path(&self) -> PathBuf {
        self.out.join("drops.csv")
    }

    /// drops.csv, read again when it changed.
    fn records(&self) -> Result<Arc<Vec<DropRecord>>, Response> {
        let path = self.drops_path();
        let now = stamp(&path);
        let mut cached = self.drops.lock().map_err(|_| busy())?;
        if let Some((s, r)) = cached.as_ref() {
            if *s == now {
                return Ok(Arc::clone(r));
            }
        }
        let records = crate::dataset::read_csv(&path)
            .map_err(|e| Response::error(500, format!("cannot read the drops: {e}")))?;
        let records = Arc::new(records);
        *cached = Some((now, Arc::clone(&records)));
        Ok(records)
    }

    /// The decisions in the review file as it is now.
    fn decisions(&self) -> Result<Decisions, Response> {
        Decisions::read_in(&self.out, &self.review_rel).map_err(|e| {
            Response::error(
                409,
                format!("{e}: correct the file (or move it away) and reload the page"),
            )
        })
    }

    /// Run `run` of drops.csv, after the checks a run name passes.
    fn record(&self, run: Option<&str>) -> Result<(Arc<Vec<DropRecord>>, usize), Response> {
        let run = run.ok_or_else(|| Response::error(400, "no run named (run=…)"))?;
        check_run_name(run)?;
        let records = self.records()?;
        let i = records.iter().position(|r| r.run == run).ok_or_else(|| {
            Response::error(
                404,
                format!(
                    "no run `{}` in {}",
                    one_line(run),
                    self.drops_path().display()
                ),
            )
        })?;
        Ok((records, i))
    }

    /// Run `rec` opened (its source, background and track), opened again
    /// when its track CSV changed; at most [`RUNS_OPEN`] held.
    fn opened(&self, rec: &DropRecord) -> Result<Arc<Mutex<Opened>>, Response> {
        let track_rel = format!("tracks/{}.csv", rec.run);
        let track = crate::util::io::inside(&self.out, &track_rel)
            .map_err(|e| Response::error(400, e.to_string()))?;
        let now = stamp(&track);
        {
            let mut runs = self.runs.lock().map_err(|_| busy())?;
            if let Some(k) = runs.iter().position(|(r, s, _)| *r == rec.run && *s == now) {
                let hit = runs.remove(k);
                let opened = Arc::clone(&hit.2);
                runs.push(hit);
                return Ok(opened);
            }
        }
        let rows = read_track(&self.out, &track_rel);
        let path = self.input_path(&rec.path);
        let view = match path {
            Some(p) => RunView::open(
                &p,
                &self.cfg,
                &crate::pipeline::settings::open_options(
                    &self.cfg,
                    self.number_digits.get(&rec.run).copied(),
                    rec.fps.or(self.cfg.camera.fps),
                ),
                rec.surface_row_px,
                impact_column(&rows, rec),
                rec.mm_per_px,
            ),
            None => Err(format!(
                "the run's input `{}` is not there (relative paths are taken from the folder \
                 `dropscope review` was started in, then from the output folder's)",
                rec.path
            )),
        };
        let frames = match &view {
            Ok(v) => v.frames.clone(),
            Err(_) => rows.iter().map(|r| r.frame).collect(),
        };
        let opened = Arc::new(Mutex::new(Opened { view, rows, frames }));
        let mut runs = self.runs.lock().map_err(|_| busy())?;
        runs.retain(|(r, _, _)| *r != rec.run);
        runs.push((rec.run.clone(), now, Arc::clone(&opened)));
        if runs.len() > RUNS_OPEN {
            runs.remove(0);
        }
        Ok(opened)
    }

    /// A run's input as drops.csv names it: as given, else from the
    /// output folder's parent.
    fn input_path(&self, path: &str) -> Option<PathBuf> {
        if path.is_empty() {
            return None;
        }
        let p = PathBuf::from(path);
        if p.exists() {
            return Some(p);
        }
        let beside = self.out.parent()?.join(&p);
        (p.is_relative() && beside.exists()).then_some(beside)
    }
}

fn busy() -> Response {
    Response::error(503, "the server is shutting down after an internal error")
}

/// A run name as a parameter: a name, never a path.
fn check_run_name(run: &str) -> Result<(), Response> {
    if run.contains(['/', '\\']) || run == ".." || run == "." {
        return Err(Response::error(
            400,
            format!("run `{}`: a run name, not a path", one_line(run)),
        ));
    }
    crate::dataset::run_name::check(run).map_err(|e| Response::error(400, e))
}

/// The rows of the track CSV `out/rel`, read through no link below the
/// output folder ([`crate::util::out_folder::read`]); none when it is not there
/// or unreadable.
fn read_track(out: &Path, rel: &str) -> Vec<TrackRow> {
    let Ok(Some(bytes)) = crate::util::out_folder::read(out, rel, 1 << 30) else {
        return Vec::new();
    };
    csv::Reader::from_reader(bytes.as_slice())
        .deserialize()
        .map_while(Result::ok)
        .collect()
}

fn api_drops(state: &State) -> Result<Response, Response> {
    let records = state.records()?;
    let decisions = state.decisions()?;
    let mut j = drops_json(&records, &decisions);
    j["out"] = json!(state.out.display().to_string());
    j["review_file"] = json!(state.out.join(&state.review_rel).display().to_string());
    j["decisions"] = json!(decisions.rows);
    Ok(Response::json(&j))
}

fn api_run(state: &State, req: &Request) -> Result<Response, Response> {
    let (records, i) = state.record(req.param("run"))?;
    let rec = &records[i];
    let decisions = state.decisions()?;
    let opened = state.opened(rec)?;
    let o = opened.lock().map_err(|_| busy())?;
    let (image_surface, w, h, fps, problem) = match &o.view {
        Ok(v) => (
            v.image_surface(),
            v.meta.width,
            v.meta.height,
            v.meta.fps,
            v.problem(),
        ),
        Err(e) => (None, 0, 0, 0.0, Some(e.clone())),
    };
    let data = RunData {
        record: rec,
        rows: &o.rows,
        frames: &o.frames,
        decisions: &decisions,
        image_surface,
        width_px: w,
        height_px: h,
        fps,
        problem,
    };
    Ok(Response::json(&data.to_json()))
}

/// A frame number parameter.
fn frame_param(v: Option<&str>) -> Result<i64, Response> {
    let v = v.ok_or_else(|| Response::error(400, "no frame given (frame=…)"))?;
    v.parse::<i64>().map_err(|_| {
        Response::error(
            400,
            format!("frame `{}`: not a camera image number", one_line(v)),
        )
    })
}

/// "frames A to B" of a run, for messages.
fn span(frames: &[i64]) -> String {
    match (frames.first(), frames.last()) {
        (Some(a), Some(b)) => format!("frames {a} to {b}"),
        _ => "no frames".into(),
    }
}

fn api_frame(state: &State, req: &Request) -> Result<Response, Response> {
    let (records, i) = state.record(req.param("run"))?;
    let rec = &records[i];
    let frame = frame_param(req.param("frame"))?;
    let view = match req.param("view") {
        None => View::Sphere,
        Some(w) => View::from_word(w).ok_or_else(|| {
            Response::error(
                400,
                format!("view `{}`: sphere, contact or frame", one_line(w)),
            )
        })?,
    };
    let decisions = state.decisions()?;
    let excluded = decisions.for_run(&rec.run).excludes(frame);
    let opened = state.opened(rec)?;
    let mut o = opened.lock().map_err(|_| busy())?;
    let Opened {
        view: v,
        rows,
        frames,
    } = &mut *o;
    if frames.binary_search(&frame).is_err() {
        return Err(Response::error(
            404,
            format!(
                "frame {frame} is not in run `{}` ({})",
                rec.run,
                span(frames)
            ),
        ));
    }
    let v = v
        .as_mut()
        .map_err(|e| Response::error(409, format!("cannot read the run's frames: {e}")))?;
    let k = rows.iter().position(|r| r.frame == frame);
    let row = k.map(|k| &rows[k]);
    let before: Vec<&TrackRow> =
        k.map_or_else(Vec::new, |k| rows[k.saturating_sub(3)..k].iter().collect());
    let (png, shown) = v
        .draw(frame, row, &before, excluded, view)
        .map_err(|e| Response::error(500, format!("frame {frame}: {e}")))?;
    Ok(Response::new(200, "image/png", png).with(
        "X-Dropscope-View",
        format!("{} {} {}", shown.x0, shown.z0, shown.zoom),
    ))
}

/// A decision as the page sends it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Asked {
    run: String,
    decision: String,
    #[serde(default)]
    frames: Option<String>,
    #[serde(default)]
    value: Option<f64>,
    #[serde(default)]
    reason: String,
}

fn parse_body<T: serde::de::DeserializeOwned>(req: &Request) -> Result<T, Response> {
    serde_json::from_slice(&req.body).map_err(|e| {
        Response::error(
            400,
            format!("the decision is not the JSON the page sends: {e}"),
        )
    })
}

fn kind(word: &str) -> Result<Kind, Response> {
    Kind::from_word(word).ok_or_else(|| {
        Response::error(
            400,
            format!(
                "decision `{}`: reject, exclude, surface or accept",
                one_line(word)
            ),
        )
    })
}

/// The run's decisions after a change, as the page lists them.
fn run_decisions(d: &Decisions, run: &str) -> Response {
    let rows: Vec<&Decision> = d.rows.iter().filter(|r| r.run == run).collect();
    Response::json(&json!({ "saved": true, "decisions": rows }))
}

fn api_decide(state: &State, req: &Request) -> Result<Response, Response> {
    let asked: Asked = parse_body(req)?;
    let (records, i) = state.record(Some(&asked.run))?;
    let rec = &records[i];
    let k = kind(&asked.decision)?;
    let frames = match asked.frames.as_deref().map(str::trim) {
        None | Some("") => None,
        Some(t) => Some(Frames::parse(t).map_err(|m| Response::error(400, format!("frames {m}")))?),
    };
    let d = Decision::new(&rec.run, k, frames, asked.value, &asked.reason)
        .map_err(|m| Response::error(400, m))?;
    if k == Kind::Exclude || k == Kind::Surface {
        let opened = state.opened(rec)?;
        let o = opened.lock().map_err(|_| busy())?;
        if let Some(f) = d.frames {
            if !frames_in(&o.frames, f) {
                return Err(Response::error(
                    404,
                    format!(
                        "frames {f} are not all in run `{}` ({})",
                        rec.run,
                        span(&o.frames)
                    ),
                ));
            }
        }
        if let (Some(row), Ok(v)) = (d.value, &o.view) {
            let h = v.meta.height as f64;
            if !(-0.5..=h - 0.5).contains(&row) {
                return Err(Response::error(
                    400,
                    format!(
                        "surface row {row}: outside the frame (rows 0 to {})",
                        h - 1.0
                    ),
                ));
            }
        }
    }
    let _one = state.writing.lock().map_err(|_| busy())?;
    let mut all = state.decisions()?;
    all.add(d);
    all.write_in(&state.out, &state.review_rel)
        .map_err(|e| Response::error(500, format!("not saved: {e}")))?;
    Ok(run_decisions(&all, &rec.run))
}

/// A decision to withdraw, as the page sends it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Withdrawn {
    run: String,
    decision: String,
    #[serde(default)]
    frames: Option<String>,
}

fn api_withdraw(state: &State, req: &Request) -> Result<Response, Response> {
    let asked: Withdrawn = parse_body(req)?;
    let (records, i) = state.record(Some(&asked.run))?;
    let run = &records[i].run;
    let k = kind(&asked.decision)?;
    let frames = match asked.frames.as_deref().map(str::trim) {
        None | Some("") => None,
        Some(t) => Some(Frames::parse(t).map_err(|m| Response::error(400, format!("frames {m}")))?),
    };
    let _one = state.writing.lock().map_err(|_| busy())?;
    let mut all = state.decisions()?;
    if all.withdraw(run, k, frames) == 0 {
        return Err(Response::error(
            404,
            format!("no `{}` decision about run `{run}` to withdraw", k.word()),
        ));
    }
    all.write_in(&state.out, &state.review_rel)
        .map_err(|e| Response::error(500, format!("not saved: {e}")))?;
    Ok(run_decisions(&all, run))
}
