//! The server's refusals of bad requests (each changes nothing), its
//! one-review-per-folder lock and its stop on Ctrl-C.

use super::*;
use dropscope::dataset::decisions::Decisions;

/// `POST target` with a JSON `body` and `headers` to the review on `port`:
/// the status and the body as text.
fn json_post(port: u16, target: &str, body: &str, headers: &[(&str, &str)]) -> (u16, String) {
    let mut h = vec![("Content-Type", "application/json")];
    h.extend_from_slice(headers);
    let (s, _, b) = http(port, "POST", target, &h, body.as_bytes());
    (s, text(&b))
}

/// A refused request: what it is, its status and body, what the refusal says.
type Refused<W> = (W, (u16, String), &'static str);

/// Every request that is not the page's own, or names what is not in the
/// folder, gets a 4xx saying what was wrong and changes nothing; a second
/// review of the folder is told it is open; Ctrl-C stops the first and
/// frees the folder.
#[test]
fn bad_requests_are_refused_and_change_nothing_and_ctrl_c_stops_the_review() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    crate::run::fixture_manifest(d);
    let out = d.join("out");
    let cfg = write_config(d, &d.join("runs.csv"), &out);
    let job = dropscope(d, &["run", "--config", cfg.to_str().unwrap()]);
    assert!(job.status.success(), "{}", text(&job.stderr));
    let review = Review::start(d, &out, &cfg);
    let (port, t) = (review.port, review.token.clone());
    let run = "R4.5mm_H12cm_01";

    assert_the_pages_own_requests_are_answered(&review, run);
    let origin = format!("http://127.0.0.1:{port}");
    let file = out.join("review.csv");
    let before = decide_one(port, &t, run, &origin, &file);
    let drops_before = std::fs::read(out.join("drops.csv")).unwrap();

    let refusals = refused_gets(port, &t, run);
    let mut posts = refused_posts_by_their_form(port, &t, run, &origin);
    posts.extend(refused_decisions(port, &t, run, &origin));
    for (what, (status, body), says) in refusals
        .iter()
        .map(|(w, r, s)| (w.as_str(), r.clone(), *s))
        .chain(posts)
    {
        assert!(
            (400..500).contains(&status),
            "{what}: status {status}: {body}"
        );
        let message: serde_json::Value =
            serde_json::from_str(&body).unwrap_or_else(|_| panic!("{what}: not JSON: {body}"));
        let message = message["error"].as_str().unwrap_or_default();
        assert!(message.contains(says), "{what}: {status} {message:?}");
    }
    assert!(
        std::fs::read(&file).unwrap() == before,
        "review.csv changed"
    );
    assert!(
        std::fs::read(out.join("drops.csv")).unwrap() == drops_before,
        "drops.csv changed"
    );

    a_second_review_is_told_it_is_open(d, &out, &cfg, &review);

    // Ctrl-C stops it, frees the folder and says where the decisions are.
    let (status, said) = review.interrupt();
    assert!(status.success(), "{status}: {said}");
    assert!(said.contains("review stopped"), "{said}");
    assert!(!out.join(".dropscope.review.lock").exists());
    assert!(std::net::TcpStream::connect(("127.0.0.1", port)).is_err());
}

/// What the page asks for, answered; nothing from the network.
fn assert_the_pages_own_requests_are_answered(review: &Review, run: &str) {
    let t = &review.token;
    let (s, page) = review.get(&format!("/?token={t}"));
    assert_eq!(s, 200);
    assert!(text(&page).contains(&format!("/page.js?token={t}")));
    // Nothing from the network: the page, its script and its style name no
    // other server (the one `http` in the script is SVG's namespace, a
    // name, not a request).
    for part in ["/", "/page.js", "/page.css"] {
        let (s, body) = review.get(&format!("{part}?token={t}"));
        assert_eq!(s, 200);
        let body = text(&body).replace("'http://www.w3.org/2000/svg'", "");
        assert!(
            !body.contains("http:") && !body.contains("https:") && !body.contains("//cdn"),
            "{part} names another server"
        );
    }
    let (s, body) = review.get(&format!(
        "/api/frame?token={t}&run={run}&frame=-30&view=contact"
    ));
    assert_eq!(s, 200);
    assert!(body.starts_with(b"\x89PNG"));
}

/// A decision the page makes is taken, and written to review.csv (`file`)
/// as a text cell: review.csv's bytes after it.
fn decide_one(port: u16, t: &str, run: &str, origin: &str, file: &Path) -> Vec<u8> {
    let (s, b) = json_post(
        port,
        &format!("/api/decide?token={t}"),
        &format!(r#"{{"run":"{run}","decision":"exclude","frames":"-3:-2","reason":"=dust"}}"#),
        &[("Origin", origin)],
    );
    assert_eq!(s, 200, "{b}");
    let before = std::fs::read(file).unwrap();
    assert!(
        text(&before).ends_with(&format!("{run},exclude,-3:-2,,'=dust,{}\n", {
            let d = Decisions::read(file).unwrap();
            d.rows[0].time.clone()
        })),
        "{}",
        text(&before)
    );
    before
}

/// The GET requests refused, made in order.
fn refused_gets(port: u16, t: &str, run: &str) -> Vec<Refused<String>> {
    let get = |target: String, headers: &[(&str, &str)]| {
        let (s, _, b) = http(port, "GET", &target, headers, b"");
        (s, text(&b))
    };
    vec![
        ("no token".into(), get("/api/drops".into(), &[]), "no token"),
        (
            "a wrong token".into(),
            get(format!("/api/drops?token={}", "0".repeat(32)), &[]),
            "wrong token",
        ),
        (
            "the token twice".into(),
            get(format!("/api/drops?token={t}&token={t}"), &[]),
            "wrong token",
        ),
        (
            "the page without its token".into(),
            get("/".into(), &[]),
            "no token",
        ),
        (
            "another Host (DNS rebinding)".into(),
            get(
                format!("/api/drops?token={t}"),
                &[("Host", &format!("evil.example:{port}"))],
            ),
            "Host `evil.example",
        ),
        (
            "another origin".into(),
            get(
                format!("/api/drops?token={t}"),
                &[("Origin", "http://evil.example")],
            ),
            "another origin",
        ),
        (
            "another site".into(),
            get(
                format!("/api/drops?token={t}"),
                &[("Sec-Fetch-Site", "cross-site")],
            ),
            "another site",
        ),
        (
            "an unknown run".into(),
            get(format!("/api/run?token={t}&run=nope"), &[]),
            "no run `nope` in",
        ),
        (
            "a path for a run".into(),
            get(
                format!("/api/run?token={t}&run=..%2F..%2Fetc%2Fpasswd"),
                &[],
            ),
            "a run name, not a path",
        ),
        (
            "a path in the address".into(),
            get(format!("/..%2F..%2Fetc%2Fpasswd?token={t}"), &[]),
            "no page",
        ),
        (
            "a parameter naming a file".into(),
            get(
                format!("/api/run?token={t}&run={run}&file=%2Fetc%2Fpasswd"),
                &[],
            ),
            "unknown parameter `file`",
        ),
        (
            "a frame out of range".into(),
            get(format!("/api/frame?token={t}&run={run}&frame=99999"), &[]),
            "frame 99999 is not in run `R4.5mm_H12cm_01` (frames -30 to 56)",
        ),
        (
            "a frame that is no number".into(),
            get(format!("/api/frame?token={t}&run={run}&frame=..%2F1"), &[]),
            "not a camera image number",
        ),
        (
            "an unknown view".into(),
            get(
                format!("/api/frame?token={t}&run={run}&frame=0&view=..%2Fx"),
                &[],
            ),
            "sphere, contact or frame",
        ),
        (
            "a GET of a decision".into(),
            get(format!("/api/decide?token={t}"), &[]),
            "takes POST only",
        ),
    ]
}

/// The decisions refused for how they are sent, made in order.
fn refused_posts_by_their_form(
    port: u16,
    t: &str,
    run: &str,
    origin: &str,
) -> Vec<Refused<&'static str>> {
    let decide = format!("/api/decide?token={t}");
    let post = |body: &str, headers: &[(&str, &str)]| json_post(port, &decide, body, headers);
    vec![
        (
            "a decision without Origin",
            post(
                &format!(r#"{{"run":"{run}","decision":"reject","reason":"x"}}"#),
                &[],
            ),
            "no Origin",
        ),
        (
            "a decision from another origin",
            post(
                &format!(r#"{{"run":"{run}","decision":"reject","reason":"x"}}"#),
                &[("Origin", "http://evil.example")],
            ),
            "another origin",
        ),
        (
            "a decision as a form",
            {
                let (s, _, b) = http(
                    port,
                    "POST",
                    &decide,
                    &[
                        ("Origin", origin),
                        ("Content-Type", "application/x-www-form-urlencoded"),
                    ],
                    b"run=x",
                );
                (s, text(&b))
            },
            "application/json",
        ),
    ]
}

/// The decisions refused for what they say, made in order.
fn refused_decisions(port: u16, t: &str, run: &str, origin: &str) -> Vec<Refused<&'static str>> {
    let decide = format!("/api/decide?token={t}");
    let post = |body: &str, headers: &[(&str, &str)]| json_post(port, &decide, body, headers);
    let o: &[(&str, &str)] = &[("Origin", origin)];
    vec![
        (
            "a decision about an unknown run",
            post(r#"{"run":"nope","decision":"reject","reason":"x"}"#, o),
            "no run `nope`",
        ),
        (
            "a decision about a path",
            post(
                r#"{"run":"../../etc/passwd","decision":"reject","reason":"x"}"#,
                o,
            ),
            "a run name, not a path",
        ),
        (
            "frames out of range",
            post(
                &format!(r#"{{"run":"{run}","decision":"exclude","frames":"50:99","reason":"x"}}"#),
                o,
            ),
            "frames 50:99 are not all in run",
        ),
        (
            "a surface outside the frame",
            post(
                &format!(r#"{{"run":"{run}","decision":"surface","value":5000,"reason":"x"}}"#),
                o,
            ),
            "outside the frame",
        ),
        (
            "a reject without a reason",
            post(
                &format!(r#"{{"run":"{run}","decision":"reject","reason":" "}}"#),
                o,
            ),
            "needs a reason",
        ),
        (
            "an unknown decision",
            post(
                &format!(r#"{{"run":"{run}","decision":"delete","reason":"x"}}"#),
                o,
            ),
            "reject, exclude, surface or accept",
        ),
        (
            "a field naming a file",
            post(
                &format!(
                    r#"{{"run":"{run}","decision":"reject","reason":"x","path":"/etc/passwd"}}"#
                ),
                o,
            ),
            "unknown field `path`",
        ),
        (
            "a body that is no JSON",
            post("{run", o),
            "not the JSON the page sends",
        ),
        (
            "a withdrawal of nothing",
            json_post(
                port,
                &format!("/api/withdraw?token={t}"),
                &format!(r#"{{"run":"{run}","decision":"reject"}}"#),
                o,
            ),
            "no `reject` decision",
        ),
    ]
}

/// A second review of the folder is told it is open.
fn a_second_review_is_told_it_is_open(d: &Path, out: &Path, cfg: &Path, review: &Review) {
    let second = dropscope(
        d,
        &[
            "review",
            out.to_str().unwrap(),
            "--config",
            cfg.to_str().unwrap(),
        ],
    );
    assert_eq!(second.status.code(), Some(2));
    let e = text(&second.stderr);
    assert!(
        e.contains("is already open for review")
            && e.contains(&format!("pid {}", review.child.id())),
        "{e}"
    );
}
