//! One HTTP/1.1 request read from a connection, one response written to
//! it: the little of the protocol the review page needs, with limits on
//! everything a client sends (a request line and headers of at most
//! [`MAX_HEAD_BYTES`], a body of at most [`MAX_BODY_BYTES`] given by
//! `Content-Length`, no chunked bodies), and every response closing its
//! connection with the headers that keep it to this page (no caching, no
//! sniffing, no framing, scripts and pictures from this server only).

use std::io::{BufRead, Read, Write};

/// The most bytes of a request line and its headers.
pub const MAX_HEAD_BYTES: usize = 16 << 10;
/// The most headers in a request.
pub const MAX_HEADERS: usize = 64;
/// The largest request body (a decision is a few hundred bytes).
pub const MAX_BODY_BYTES: usize = 64 << 10;

/// A request as read.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    /// The method (`GET`, `POST`, …), as sent.
    pub method: String,
    /// The path, percent-decoded, without the query.
    pub path: String,
    /// The query's parameters, percent-decoded, in order.
    pub query: Vec<(String, String)>,
    /// Header names in lower case, values trimmed.
    pub headers: Vec<(String, String)>,
    /// The body (at most [`MAX_BODY_BYTES`]).
    pub body: Vec<u8>,
}

impl Request {
    /// The value of header `name` (lower case), if sent once or more (the first).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// How many times header `name` (lower case) was sent.
    pub fn header_count(&self, name: &str) -> usize {
        self.headers.iter().filter(|(n, _)| n == name).count()
    }

    /// The value of query parameter `name`, if given (the first).
    pub fn param(&self, name: &str) -> Option<&str> {
        self.query
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// A response to write.
#[derive(Debug, Clone, PartialEq)]
pub struct Response {
    /// The status code.
    pub status: u16,
    /// The `Content-Type` header's value.
    pub content_type: &'static str,
    /// Headers besides those every response carries.
    pub headers: Vec<(&'static str, String)>,
    /// The body.
    pub body: Vec<u8>,
}

impl Response {
    /// `status` with `body` of type `content_type`.
    pub fn new(status: u16, content_type: &'static str, body: Vec<u8>) -> Self {
        Response {
            status,
            content_type,
            headers: Vec::new(),
            body,
        }
    }

    /// 200 with a JSON document.
    pub fn json(value: &serde_json::Value) -> Self {
        let mut body = serde_json::to_vec(value).unwrap_or_default();
        body.push(b'\n');
        Response::new(200, "application/json; charset=utf-8", body)
    }

    /// An error: `{"error": message}` with `status`, which the page shows
    /// as it is.
    pub fn error(status: u16, message: impl Into<String>) -> Self {
        let mut body =
            serde_json::to_vec(&serde_json::json!({ "error": message.into() })).unwrap_or_default();
        body.push(b'\n');
        Response::new(status, "application/json; charset=utf-8", body)
    }

    /// `self` with header `name: value` too.
    pub fn with(mut self, name: &'static str, value: String) -> Self {
        self.headers.push((name, value));
        self
    }
}

/// The reason phrase of the statuses this server sends.
fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        409 => "Conflict",
        411 => "Length Required",
        413 => "Content Too Large",
        415 => "Unsupported Media Type",
        421 => "Misdirected Request",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        501 => "Not Implemented",
        503 => "Service Unavailable",
        505 => "HTTP Version Not Supported",
        _ => "",
    }
}

/// The content security policy of every response: nothing but this
/// server's own script, style, pictures and requests.
pub const CSP: &str = "default-src 'none'; script-src 'self'; style-src 'self'; \
                       img-src 'self' blob:; connect-src 'self'; base-uri 'none'; \
                       form-action 'none'; frame-ancestors 'none'";

/// Write `r` and close: status line, the headers every response carries,
/// its own, the body.
pub fn write_response(out: &mut impl Write, r: &Response) -> std::io::Result<()> {
    let mut head = format!(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nConnection: close\r\n\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nX-Frame-Options: DENY\r\n\
         Referrer-Policy: no-referrer\r\nCross-Origin-Resource-Policy: same-origin\r\n\
         Content-Security-Policy: {CSP}\r\n",
        r.status,
        reason(r.status),
        r.content_type,
        r.body.len()
    );
    for (n, v) in &r.headers {
        // Header values are made here, never from the request: still, no
        // line breaks.
        let v: String = v.chars().filter(|c| !c.is_control()).collect();
        head.push_str(&format!("{n}: {v}\r\n"));
    }
    head.push_str("\r\n");
    out.write_all(head.as_bytes())?;
    out.write_all(&r.body)?;
    out.flush()
}

/// Why no request was read.
#[derive(Debug)]
pub enum ReadError {
    /// The connection closed (or timed out) before a whole request.
    Closed,
    /// What the client sent is not a request this server takes: answered
    /// with this response.
    Refused(Response),
}

/// Read one request from `input` (see the module doc for the limits).
pub fn read_request(input: &mut impl BufRead) -> Result<Request, ReadError> {
    let refuse = |status: u16, m: &str| ReadError::Refused(Response::error(status, m));
    let mut head: Vec<String> = Vec::new();
    let mut bytes = 0usize;
    loop {
        let mut line = Vec::new();
        let limit = (MAX_HEAD_BYTES - bytes + 1) as u64;
        let n = input
            .by_ref()
            .take(limit)
            .read_until(b'\n', &mut line)
            .map_err(|_| ReadError::Closed)?;
        if n == 0 {
            return Err(ReadError::Closed);
        }
        bytes += n;
        if bytes > MAX_HEAD_BYTES || !line.ends_with(b"\n") {
            if bytes > MAX_HEAD_BYTES {
                return Err(refuse(431, "the request's head is longer than 16 KiB"));
            }
            return Err(ReadError::Closed);
        }
        let text = String::from_utf8(line)
            .map_err(|_| refuse(400, "the request's head is not UTF-8 text"))?;
        let text = text.trim_end_matches(['\r', '\n']).to_string();
        if text.is_empty() {
            if head.is_empty() {
                // Blank lines before a request line are allowed (RFC 9112 §2.2).
                continue;
            }
            break;
        }
        head.push(text);
        if head.len() > MAX_HEADERS + 1 {
            return Err(refuse(431, "more than 64 headers"));
        }
    }
    let mut parts = head[0].split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(refuse(
            400,
            "the request line is not `METHOD TARGET HTTP/1.1`",
        ));
    };
    if version != "HTTP/1.1" && version != "HTTP/1.0" {
        return Err(refuse(505, "only HTTP/1.1 and HTTP/1.0"));
    }
    if !target.starts_with('/') {
        return Err(refuse(400, "the request target is not a path"));
    }
    let (raw_path, raw_query) = target.split_once('?').unwrap_or((target, ""));
    let path = percent_decode(raw_path, false)
        .ok_or_else(|| refuse(400, "the path is not percent-encoded UTF-8"))?;
    let mut query = Vec::new();
    for pair in raw_query.split('&').filter(|p| !p.is_empty()) {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        let (Some(k), Some(v)) = (percent_decode(k, true), percent_decode(v, true)) else {
            return Err(refuse(
                400,
                "a query parameter is not percent-encoded UTF-8",
            ));
        };
        query.push((k, v));
    }
    let mut headers = Vec::with_capacity(head.len() - 1);
    for h in &head[1..] {
        let Some((n, v)) = h.split_once(':') else {
            return Err(refuse(400, "a header line without `:`"));
        };
        if n.is_empty() || n.contains([' ', '\t']) {
            return Err(refuse(400, "a header name with white space"));
        }
        headers.push((n.to_ascii_lowercase(), v.trim().to_string()));
    }
    let mut req = Request {
        method: method.to_string(),
        path,
        query,
        headers,
        body: Vec::new(),
    };
    if req.header("transfer-encoding").is_some() {
        return Err(refuse(
            501,
            "chunked or encoded bodies are not taken: send Content-Length",
        ));
    }
    let lengths: Vec<&str> = req
        .headers
        .iter()
        .filter(|(n, _)| n == "content-length")
        .map(|(_, v)| v.as_str())
        .collect();
    let length = match lengths.as_slice() {
        [] => 0,
        [one] => one
            .parse::<usize>()
            .map_err(|_| refuse(400, "Content-Length is not a number"))?,
        _ => return Err(refuse(400, "Content-Length given more than once")),
    };
    if length > MAX_BODY_BYTES {
        return Err(refuse(413, "the body is larger than 64 KiB"));
    }
    let mut body = vec![0u8; length];
    input.read_exact(&mut body).map_err(|_| ReadError::Closed)?;
    req.body = body;
    Ok(req)
}

/// Percent-decoding of a path (`plus_space`: false) or a query part
/// (`+` is a space); `None` when not valid UTF-8 or a `%` is not followed
/// by two hex digits.
pub fn percent_decode(s: &str, plus_space: bool) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'%' => {
                let hex = |c: u8| (c as char).to_digit(16);
                let hi = hex(*b.get(i + 1)?)?;
                let lo = hex(*b.get(i + 2)?)?;
                out.push((hi * 16 + lo) as u8);
                i += 3;
            }
            b'+' if plus_space => {
                out.push(b' ');
                i += 1;
            }
            c => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8(out).ok()
}

/// Whether `a` and `b` are the same bytes, in a time that depends on their
/// length only (a token compared so leaks nothing of itself through timing).
pub fn same_secret(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &[u8]) -> Result<Request, ReadError> {
        read_request(&mut std::io::BufReader::new(text))
    }

    fn refused(text: &[u8]) -> u16 {
        match read(text) {
            Err(ReadError::Refused(r)) => r.status,
            other => panic!("not refused: {other:?}"),
        }
    }

    #[test]
    fn a_request_is_read_with_its_query_headers_and_body() {
        let r = read(
            b"POST /api/decide?token=ab%2Fc&run=R+1%20x&x HTTP/1.1\r\nHost: 127.0.0.1:8\r\n\
              Content-Length: 5\r\nOrigin:  http://127.0.0.1:8 \r\n\r\nhello extra",
        )
        .unwrap();
        assert_eq!(r.method, "POST");
        assert_eq!(r.path, "/api/decide");
        assert_eq!(r.param("token"), Some("ab/c"));
        assert_eq!(r.param("run"), Some("R 1 x"));
        assert_eq!(r.param("x"), Some(""));
        assert_eq!(r.header("origin"), Some("http://127.0.0.1:8"));
        assert_eq!(r.body, b"hello");
    }

    #[test]
    fn what_is_not_a_request_of_ours_is_refused_with_its_status() {
        assert_eq!(refused(b"GET / HTTP/2\r\n\r\n"), 505);
        assert_eq!(refused(b"GET http://x/ HTTP/1.1\r\n\r\n"), 400);
        assert_eq!(refused(b"GET / HTTP/1.1 extra\r\n\r\n"), 400);
        assert_eq!(refused(b"GET /%zz HTTP/1.1\r\n\r\n"), 400);
        assert_eq!(refused(b"GET /?a=%ff HTTP/1.1\r\n\r\n"), 400);
        assert_eq!(
            refused(b"POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n"),
            501
        );
        assert_eq!(
            refused(b"POST / HTTP/1.1\r\nContent-Length: 99999999\r\n\r\n"),
            413
        );
        assert_eq!(
            refused(b"POST / HTTP/1.1\r\nContent-Length: 1\r\nContent-Length: 1\r\n\r\nx"),
            400
        );
        let long = format!("GET /{} HTTP/1.1\r\n\r\n", "a".repeat(MAX_HEAD_BYTES));
        assert_eq!(refused(long.as_bytes()), 431);
        let many: String = (0..70).map(|i| format!("X-{i}: y\r\n")).collect();
        assert_eq!(
            refused(format!("GET / HTTP/1.1\r\n{many}\r\n").as_bytes()),
            431
        );
        assert!(matches!(
            read(b"GET / HTTP/1.1\r\nHost"),
            Err(ReadError::Closed)
        ));
        assert!(matches!(
            read(b"POST / HTTP/1.1\r\nContent-Length: 9\r\n\r\nshort"),
            Err(ReadError::Closed)
        ));
    }

    #[test]
    fn responses_carry_their_length_and_the_fencing_headers() {
        let mut out = Vec::new();
        write_response(
            &mut out,
            &Response::error(404, "no run `x`").with("X-View", "1 2\r\n3".into()),
        )
        .unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with("HTTP/1.1 404 Not Found\r\n"), "{text}");
        assert!(text.contains("Content-Length: 23\r\n"), "{text}");
        assert!(text.contains("X-View: 1 23\r\n"), "{text}");
        assert!(text.contains("Content-Security-Policy: default-src 'none'"));
        assert!(
            text.ends_with("\r\n\r\n{\"error\":\"no run `x`\"}\n"),
            "{text}"
        );
        assert!(same_secret("abc", "abc") && !same_secret("abc", "abd") && !same_secret("a", "ab"));
    }
}
