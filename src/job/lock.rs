//! One job at a time per output folder, shards of one job together.
//!
//! A command that writes into an output folder first takes a ticket in
//! `<out>/.dropscope.lock/`: a file `NNNNNNNNNN.json` holding the holder's
//! job id, shard (if any), pid, host and command line. Two holders conflict
//! when their job ids differ, or when neither is a shard: shards of one job
//! share the folder with each other and with that job's finishing run, but
//! two whole jobs never do, since each rewrites the collapse. A newcomer is
//! let in when no conflicting ticket holds the folder or waits with an
//! earlier number; otherwise it removes its ticket and is refused (or, with
//! `--wait`, tries again every half second).
//!
//! The job id is derived from the configuration and the run list (see
//! [`crate::job::cache::job_id`]), so every shard of a job computes the same id
//! without talking to the others, and another configuration is kept out.
//!
//! Only primitives that cluster file systems (NFS, Lustre, GPFS) make atomic
//! are used: a ticket is written whole to a temporary and hard-linked to its
//! number (which fails if the number is taken), and marked held by an
//! atomic rename (see [`acquire`]).
//!
//! A ticket whose process is gone (same host, pid no longer running, or
//! running a different program start) is stale: the next holder removes it
//! and says so. A ticket from another host cannot be checked and counts as
//! live; the refusal says which file to remove if that job is gone. On
//! release the holder removes its ticket, and the folder once it is empty.

use crate::util;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The lock folder inside an output folder.
pub const LOCK_DIR: &str = ".dropscope.lock";

/// How long `--wait` sleeps between attempts.
const WAIT_POLL: Duration = Duration::from_millis(500);

/// One holder of an output folder, as its ticket records it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Holder {
    /// The job id (hex): holders with the same id are parts of one job.
    pub job: String,
    /// `"K/N"` for a shard, `None` for a whole job.
    pub shard: Option<String>,
    /// The holder's process id.
    pub pid: u32,
    /// The machine the holder runs on.
    pub host: String,
    /// The process's start time in clock ticks since boot (Linux), to tell
    /// a reused pid from the holder.
    pub start_ticks: Option<u64>,
    /// The command line, for messages.
    pub command: String,
    /// Whether it holds the folder (else it is still checking the others).
    #[serde(default)]
    pub held: bool,
}

impl Holder {
    /// This process as a holder of job `job` (a shard when `shard` is given).
    pub fn this_process(job: &str, shard: Option<String>) -> Self {
        let pid = std::process::id();
        Holder {
            job: job.to_string(),
            shard,
            pid,
            host: util::io::this_host().to_string(),
            start_ticks: start_ticks(pid),
            command: std::env::args().collect::<Vec<_>>().join(" "),
            held: false,
        }
    }

    /// Whether `self` and `other` may not use one folder at once.
    fn conflicts_with(&self, other: &Holder) -> bool {
        self.job != other.job || (self.shard.is_none() && other.shard.is_none())
    }

    /// Whether the process is known to be gone: on this host, and its pid
    /// not running or running a process started at another time.
    pub fn is_gone(&self) -> bool {
        if self.host != util::io::this_host() {
            return false;
        }
        if !pid_running(self.pid) {
            return true;
        }
        match (self.start_ticks, start_ticks(self.pid)) {
            (Some(a), Some(b)) => a != b,
            _ => false,
        }
    }

    fn describe(&self) -> String {
        let part = match &self.shard {
            Some(s) => format!("shard {s} of job {}", short(&self.job)),
            None => format!("job {}", short(&self.job)),
        };
        format!(
            "{part} (pid {} on host {}: `{}`)",
            self.pid, self.host, self.command
        )
    }
}

/// The first 12 characters of a job id (any text, if a ticket was edited).
fn short(job: &str) -> &str {
    job.char_indices().nth(12).map_or(job, |(i, _)| &job[..i])
}

/// Why the folder could not be taken.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another process holds the folder.
    #[error(
        "{out} is in use by {holder}{same}: wait for it to end, or add --wait to start once it \
         has. If that process is no longer running (a crashed job on another machine), remove \
         {ticket} and try again",
        out = out.display(),
        holder = holder.describe(),
        same = if *same_job { ", the same job" } else { ", another job" },
        ticket = ticket.display()
    )]
    Busy {
        /// The output folder.
        out: PathBuf,
        /// Who holds it, as its ticket says.
        holder: Box<Holder>,
        /// Whether the holder is another part (shard) of this same job.
        same_job: bool,
        /// The holder's ticket, to remove should the process be gone.
        ticket: PathBuf,
    },
    /// The lock folder or a ticket could not be made or read.
    #[error("{path}: cannot take the output folder's lock: {source}")]
    Io {
        /// The lock folder or ticket.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
}

/// The output folder, held until dropped.
#[derive(Debug)]
pub struct FolderLock {
    ticket: PathBuf,
    dir: PathBuf,
    /// Its place among the tickets a signal releases.
    slot: Option<usize>,
}

impl FolderLock {
    /// The ticket this holder took.
    pub fn ticket(&self) -> &Path {
        &self.ticket
    }
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        on_signal::forget(self.slot);
        let _ = std::fs::remove_file(&self.ticket);
        // Fails while other holders' tickets are in it, as it should.
        let _ = std::fs::remove_dir(&self.dir);
    }
}

/// SIGTERM (Slurm's cancel and time limit, `kill`) and SIGINT (Ctrl-C)
/// release the folders this process holds before it ends: a handler
/// removes their tickets and the lock folder if empty (`unlink`, `rmdir`:
/// safe in a signal handler), then ends the process by the same signal.
/// Every file the job wrote is whole (written atomically) and each run
/// committed or not; the next job takes the folder at once, on any host.
mod on_signal {
    use std::ffi::CString;
    use std::path::Path;
    use std::sync::atomic::{AtomicPtr, Ordering};
    use std::sync::Once;

    const SLOTS: usize = 16;
    static TICKETS: [AtomicPtr<libc::c_char>; SLOTS] =
        [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];
    static DIRS: [AtomicPtr<libc::c_char>; SLOTS] =
        [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];
    static INSTALL: Once = Once::new();

    extern "C" fn release(signal: libc::c_int) {
        for (t, d) in TICKETS.iter().zip(&DIRS) {
            let (t, d) = (t.load(Ordering::SeqCst), d.load(Ordering::SeqCst));
            // SAFETY: each pointer is null or a NUL-terminated path that is
            // never freed; unlink, rmdir, signal and raise are
            // async-signal-safe.
            unsafe {
                if !t.is_null() {
                    libc::unlink(t);
                }
                if !d.is_null() {
                    libc::rmdir(d);
                }
            }
        }
        // SAFETY: as above.
        unsafe {
            libc::signal(signal, libc::SIG_DFL);
            libc::raise(signal);
        }
    }

    fn leak(p: &Path) -> *mut libc::c_char {
        use std::os::unix::ffi::OsStrExt;
        CString::new(p.as_os_str().as_bytes()).map_or(std::ptr::null_mut(), CString::into_raw)
    }

    /// Remember `ticket` (in `dir`) for the handler, installing it once.
    /// Returns its slot (`None`: all taken; the ticket is then left to the
    /// next job's stale-ticket check).
    pub fn remember(ticket: &Path, dir: &Path) -> Option<usize> {
        INSTALL.call_once(|| {
            for s in [libc::SIGTERM, libc::SIGINT] {
                // SAFETY: installs a handler that only calls async-signal-safe functions.
                unsafe {
                    libc::signal(
                        s,
                        release as extern "C" fn(libc::c_int) as libc::sighandler_t,
                    );
                }
            }
        });
        let slot = TICKETS
            .iter()
            .position(|t| t.load(Ordering::SeqCst).is_null())?;
        // The paths are leaked, never freed: the handler may read them at
        // any moment (a few bytes a lock taken).
        DIRS[slot].store(leak(dir), Ordering::SeqCst);
        TICKETS[slot].store(leak(ticket), Ordering::SeqCst);
        Some(slot)
    }

    /// The ticket of `slot` is released: the handler no longer removes it.
    pub fn forget(slot: Option<usize>) {
        if let Some(s) = slot {
            TICKETS[s].store(std::ptr::null_mut(), Ordering::SeqCst);
            DIRS[s].store(std::ptr::null_mut(), Ordering::SeqCst);
        }
    }
}

/// Whether process `pid` exists on this machine.
fn pid_running(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: kill with signal 0 only checks that the process exists.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Whether the writer of a temporary, process `pid` on `host`, is known to
/// have ended (see [`crate::util::io::remove_stale_temporaries`]).
pub fn writer_is_gone(pid: u32, host: &str) -> bool {
    host == util::io::this_host() && !pid_running(pid)
}

/// Start time of process `pid` in clock ticks since boot (field 22 of
/// `/proc/<pid>/stat`), where there is a `/proc`.
fn start_ticks(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (field 2) may hold spaces; fields after it do not.
    let rest = &stat[stat.rfind(')')? + 1..];
    rest.split_whitespace().nth(19)?.parse().ok()
}

fn ticket_number(name: &str) -> Option<u64> {
    let n = name.strip_suffix(".json")?;
    (n.len() == 10 && n.bytes().all(|b| b.is_ascii_digit()))
        .then(|| n.parse().ok())
        .flatten()
}

/// The tickets in `dir`, by number.
fn tickets(dir: &Path) -> std::io::Result<Vec<(u64, PathBuf)>> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        if let Some(n) = ticket_number(&e.file_name().to_string_lossy()) {
            v.push((n, e.path()));
        }
    }
    v.sort();
    Ok(v)
}

/// A ticket's holder; `None` when it vanished meanwhile (released).
fn read_ticket(path: &Path) -> std::io::Result<Option<Holder>> {
    match std::fs::read(path) {
        Ok(bytes) => serde_json::from_slice(&bytes)
            .map(Some)
            .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e),
    }
}

/// Take the next free ticket number: one above the highest ticket seen.
fn take_ticket(dir: &Path, me: &Holder) -> std::io::Result<(u64, PathBuf)> {
    // Unique per process (pid, host) and per call (threads of one process).
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = util::io::temporary_path(&dir.join(format!("ticket{call}")))?;
    std::fs::write(&tmp, ticket_bytes(me)?)?;
    let taken = (|| {
        let mut n = tickets(dir)?.last().map_or(1, |(n, _)| n + 1);
        loop {
            let path = dir.join(format!("{n:010}.json"));
            match std::fs::hard_link(&tmp, &path) {
                Ok(()) => return Ok((n, path)),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => n += 1,
                Err(e) => return Err(e),
            }
        }
    })();
    let _ = std::fs::remove_file(&tmp);
    taken
}

fn ticket_bytes(h: &Holder) -> std::io::Result<Vec<u8>> {
    let mut bytes = serde_json::to_vec_pretty(h).map_err(std::io::Error::other)?;
    bytes.push(b'\n');
    Ok(bytes)
}

/// The first live holder among the other tickets that keeps `me` (ticket
/// `mine`) out: a conflicting one that holds the folder, or (when
/// `pending_too`) one waiting with an earlier number. Stale tickets met on
/// the way are removed and reported through `notify`.
fn blocker(
    out: &Path,
    dir: &Path,
    me: &Holder,
    mine: u64,
    pending_too: bool,
    notify: &dyn Fn(&str),
) -> Result<Option<(Holder, PathBuf)>, LockError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| LockError::Io { path, source }
    };
    for (n, path) in tickets(dir).map_err(io(dir))? {
        if n == mine {
            continue;
        }
        let holder = match read_ticket(&path) {
            Ok(Some(h)) => h,
            Ok(None) => continue,
            // Tickets are written whole before they are linked in: an
            // empty or damaged one is what a power cut or a full disk
            // left, and names no process to wait for.
            Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
                util::io::remove_if_present(&path).map_err(io(&path))?;
                notify(&format!(
                    "{}: took over the lock: its ticket {} was empty or damaged, as a power \
                     cut or a full disk leaves it (removed)",
                    out.display(),
                    path.display()
                ));
                continue;
            }
            Err(e) => return Err(io(&path)(e)),
        };
        if holder.is_gone() {
            util::io::remove_if_present(&path).map_err(io(&path))?;
            notify(&format!(
                "{}: took over the lock of {}: that process is gone",
                out.display(),
                holder.describe()
            ));
        } else if holder.conflicts_with(me) && (holder.held || (pending_too && n < mine)) {
            return Ok(Some((holder, path)));
        }
    }
    Ok(None)
}

/// Take output folder `out` for `me`. Stale tickets met on the way are
/// removed and reported through `notify`; a conflicting live holder
/// refuses, or with `wait` is waited for (reported once through `notify`).
///
/// A ticket is taken pending; it is marked held (rewritten atomically)
/// once no conflicting ticket holds the folder or waits with an earlier
/// number, and then checked once more: of two conflicting holders marked
/// at once, the later mark sees the earlier and yields, so two conflicting
/// holders are never in together.
pub fn acquire(
    out: &Path,
    me: &Holder,
    wait: bool,
    notify: &dyn Fn(&str),
) -> Result<FolderLock, LockError> {
    acquire_in(out, LOCK_DIR, me, wait, notify)
}

/// [`acquire`] with the tickets in `out/<lock_dir>`: a lock of its own
/// beside the jobs' (`dropscope review` holds `.dropscope.review.lock`, so
/// that a second review of the folder is told it is open, while jobs
/// still write into it).
pub fn acquire_in(
    out: &Path,
    lock_dir: &str,
    me: &Holder,
    wait: bool,
    notify: &dyn Fn(&str),
) -> Result<FolderLock, LockError> {
    let dir = out.join(lock_dir);
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| LockError::Io { path, source }
    };
    let mut told_waiting = false;
    loop {
        // Another holder's release may remove the empty folder at any
        // moment: between create_dir's "exists" and its check that a folder
        // is there (create_dir_all then says AlreadyExists), or before the
        // sweep lists it (NotFound). Both mean: again. Only something that
        // is not a folder in its place is an error.
        let not_a_folder = || std::fs::symlink_metadata(&dir).is_ok_and(|m| !m.is_dir());
        // A link planted in its place would take the tickets elsewhere.
        if std::fs::symlink_metadata(&dir).is_ok_and(|m| m.file_type().is_symlink()) {
            return Err(LockError::Io {
                path: dir.clone(),
                source: std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "is a symbolic link, not the lock folder dropscope makes; remove it",
                ),
            });
        }
        match std::fs::create_dir_all(&dir) {
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && !not_a_folder() => continue,
            r => r.map_err(io(&dir))?,
        }
        match util::io::remove_stale_temporaries(&dir, &writer_is_gone) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            r => r.map(drop).map_err(io(&dir))?,
        }
        let (mine, ticket) = match take_ticket(&dir, me) {
            Ok(t) => t,
            // The last holder removed the empty lock folder just now.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(e) => return Err(io(&dir)(e)),
        };
        let mut found = blocker(out, &dir, me, mine, true, notify);
        if let Ok(None) = found {
            let held = Holder {
                held: true,
                ..me.clone()
            };
            let marked = ticket_bytes(&held).and_then(|b| util::io::write_atomic(&ticket, &b));
            if let Err(source) = marked {
                let _ = std::fs::remove_file(&ticket);
                return Err(LockError::Io {
                    path: ticket,
                    source,
                });
            }
            found = blocker(out, &dir, me, mine, false, notify);
        }
        let found = found.inspect_err(|_| {
            let _ = std::fs::remove_file(&ticket);
        })?;
        let Some((holder, path)) = found else {
            let slot = on_signal::remember(&ticket, &dir);
            return Ok(FolderLock { ticket, dir, slot });
        };
        util::io::remove_if_present(&ticket).map_err(io(&ticket))?;
        if !wait {
            let _ = std::fs::remove_dir(&dir);
            return Err(LockError::Busy {
                out: out.to_path_buf(),
                same_job: holder.job == me.job,
                holder: Box::new(holder),
                ticket: path,
            });
        }
        if !told_waiting {
            notify(&format!(
                "{}: waiting for {} to end",
                out.display(),
                holder.describe()
            ));
            told_waiting = true;
        }
        // Staggered by pid, so that two waiters do not retry in step.
        std::thread::sleep(WAIT_POLL + Duration::from_millis(u64::from(me.pid % 97)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An empty ticket (a power cut between its creation and its data
    /// reaching the disk) names no process: taken over with a message.
    #[test]
    fn an_empty_or_damaged_ticket_is_taken_over_saying_so() {
        for bytes in [&b""[..], b"{\"job\": \"x\""] {
            let dir = tempfile::tempdir().unwrap();
            let lock = dir.path().join(LOCK_DIR);
            std::fs::create_dir(&lock).unwrap();
            std::fs::write(lock.join("0000000001.json"), bytes).unwrap();
            let said = std::sync::Mutex::new(Vec::new());
            let held = acquire(dir.path(), &holder("aaa", None), false, &|m| {
                said.lock().unwrap().push(m.to_string())
            })
            .unwrap();
            let said = said.into_inner().unwrap().join("\n");
            assert!(
                said.contains("0000000001.json") && said.contains("empty or damaged"),
                "{said}"
            );
            assert!(!lock.join("0000000001.json").exists());
            drop(held);
            assert!(!lock.exists());
        }
    }

    #[test]
    fn job_ids_are_shortened_on_character_boundaries() {
        assert_eq!(short("0123456789abcdef"), "0123456789ab");
        assert_eq!(short("ééééééééééééé"), "éééééééééééé");
        assert_eq!(short("abc"), "abc");
    }

    fn holder(job: &str, shard: Option<&str>) -> Holder {
        Holder::this_process(job, shard.map(String::from))
    }

    fn quiet(_: &str) {}

    #[test]
    fn shards_of_one_job_share_and_other_jobs_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let a0 = acquire(out, &holder("aaa", Some("0/2")), false, &quiet).unwrap();
        let a1 = acquire(out, &holder("aaa", Some("1/2")), false, &quiet).unwrap();
        // The finishing run of the same job joins the shards.
        let whole = acquire(out, &holder("aaa", None), false, &quiet).unwrap();
        // A second whole run of the same job does not: both would rewrite the collapse.
        let e = acquire(out, &holder("aaa", None), false, &quiet).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("the same job") && msg.contains("--wait"),
            "{msg}"
        );
        // Another job, whole or a shard, is refused while any of job aaa holds it.
        drop(whole);
        for shard in [None, Some("0/2")] {
            let e = acquire(out, &holder("bbb", shard), false, &quiet).unwrap_err();
            let msg = e.to_string();
            assert!(
                msg.contains("another job")
                    && msg.contains(&format!("pid {}", std::process::id()))
                    && msg.contains(LOCK_DIR),
                "{msg}"
            );
        }
        assert_eq!(
            tickets(&out.join(LOCK_DIR)).unwrap().len(),
            2,
            "refused tickets left"
        );
        drop((a0, a1));
        assert!(
            !out.join(LOCK_DIR).exists(),
            "the lock folder outlived its holders"
        );
        let b = acquire(out, &holder("bbb", None), false, &quiet).unwrap();
        assert!(b.ticket().is_file());
    }

    #[test]
    fn a_dead_holder_is_taken_over_with_a_message_and_a_remote_one_is_not() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let lock = out.join(LOCK_DIR);
        std::fs::create_dir_all(&lock).unwrap();
        // A process that has ended: its pid is not running (until reused).
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let dead_pid = child.id();
        child.wait().unwrap();
        let mut dead = holder("old", None);
        dead.pid = dead_pid;
        dead.start_ticks = None;
        std::fs::write(
            lock.join("0000000007.json"),
            serde_json::to_vec(&dead).unwrap(),
        )
        .unwrap();
        // A temporary the dead process left.
        std::fs::write(
            lock.join(format!(".ticket.tmp-{dead_pid}@{}", dead.host)),
            b"",
        )
        .unwrap();
        let said = std::sync::Mutex::new(Vec::new());
        let l = acquire(out, &holder("new", None), false, &|m| {
            said.lock().unwrap().push(m.to_string())
        })
        .unwrap();
        let said = said.into_inner().unwrap();
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(
            said[0].contains("took over") && said[0].contains(&format!("pid {dead_pid}")),
            "{said:?}"
        );
        assert!(l.ticket().ends_with("0000000008.json"));
        drop(l);
        assert!(!lock.exists(), "stale files left in the lock folder");

        // Our own pid with another start time: a reused pid, so gone too.
        let mut reused = holder("old", None);
        reused.start_ticks = reused.start_ticks.map(|t| t + 1);
        assert_eq!(reused.is_gone(), reused.start_ticks.is_some());
        // On another host nothing can be known: it counts as live.
        let mut remote = dead.clone();
        remote.host = "elsewhere.example".into();
        assert!(!remote.is_gone());
    }

    #[test]
    fn holders_coming_and_going_never_fail_on_the_vanishing_lock_folder() {
        // Shards of one job take and release the folder over and over: a
        // release removes the lock folder when it empties, under the feet
        // of a newcomer, which must simply take a ticket in a new one.
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().to_path_buf();
        std::thread::scope(|s| {
            for k in 0..4 {
                let out = &out;
                s.spawn(move || {
                    let me = holder("job", Some(&format!("{k}/4")));
                    for _ in 0..200 {
                        drop(acquire(out, &me, false, &quiet).unwrap());
                    }
                });
            }
        });
        assert!(!out.join(LOCK_DIR).exists());
    }

    #[test]
    fn racing_jobs_let_exactly_one_in() {
        // Eight threads of two jobs race for an empty folder, again and
        // again: each time the winners are all of one job.
        for round in 0..20 {
            let dir = tempfile::tempdir().unwrap();
            let out = dir.path().to_path_buf();
            let barrier = std::sync::Barrier::new(8);
            let got: Vec<Option<(String, FolderLock)>> = std::thread::scope(|s| {
                let hs: Vec<_> = (0..8)
                    .map(|i| {
                        let (out, barrier) = (&out, &barrier);
                        s.spawn(move || {
                            let job = if i % 2 == 0 { "even" } else { "odd" };
                            let me = holder(job, Some(&format!("{i}/8")));
                            barrier.wait();
                            acquire(out, &me, false, &quiet)
                                .ok()
                                .map(|l| (job.to_string(), l))
                        })
                    })
                    .collect();
                hs.into_iter().map(|h| h.join().unwrap()).collect()
            });
            let jobs: std::collections::BTreeSet<&str> =
                got.iter().flatten().map(|(j, _)| j.as_str()).collect();
            assert_eq!(jobs.len(), 1, "round {round}: {jobs:?} got in together");
        }
    }
}
