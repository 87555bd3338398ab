//! The model client honours `Retry-After` on a 429 (issue 16: it retried after 0.2 s when
//! the server asked for 3 s), and names every kind of failure when it gives up.

mod support;

use agentstar_agent::llm::{
    complete_with, parse_retry_after, LlmError, Message, ModelConfig, Part, Protocol,
};
use std::io::Write;
use std::sync::Mutex;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// A server answering each request with the next (status, extra headers, body).
fn server(script: Vec<(u16, &'static str, String)>) -> String {
    let (listener, url) = support::listen();
    std::thread::spawn(move || {
        let mut script = std::collections::VecDeque::from(script);
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            support::read_request(&stream);
            let (status, headers, text) =
                script
                    .pop_front()
                    .unwrap_or((500, "", "{\"error\": \"exhausted\"}".into()));
            let _ = write!(
                stream,
                "HTTP/1.1 {status} X\r\n{headers}content-length: {}\r\nconnection: close\r\n\r\n{text}",
                text.len()
            );
        }
    });
    url
}

fn config(url: &str) -> ModelConfig {
    ModelConfig {
        protocol: Protocol::OpenAi,
        provider: "local".into(),
        model: "mock".into(),
        base_url: url.into(),
        api_key: None,
        timeout: Duration::from_secs(5),
        retries: 3,
        backoff: Duration::from_millis(200),
        max_reply_tokens: 64,
    }
}

const OK: &str = r#"{"choices": [{"message": {"content": "hello"}}]}"#;

#[test]
fn retry_after_is_honoured() {
    let url = server(vec![
        (
            429,
            "retry-after: 3\r\n",
            "{\"error\": \"slow down\"}".into(),
        ),
        (429, "", "{\"error\": \"slow down\"}".into()),
        (200, "", OK.into()),
    ]);
    let waits = Mutex::new(vec![]);
    let r = complete_with(
        &config(&url),
        "sys",
        &[Message::User(vec![Part::Text("hi".into())])],
        &[],
        &|_, _| {},
        &|d| waits.lock().expect("lock").push(d),
    )
    .expect("reply");
    assert_eq!(r.text, "hello");
    // The server's 3 s, then the doubled backoff (no header the second time).
    assert_eq!(
        *waits.lock().expect("lock"),
        [Duration::from_secs(3), Duration::from_millis(400)]
    );
}

#[test]
fn retry_after_parses_seconds_and_http_dates() {
    let now = UNIX_EPOCH + Duration::from_secs(784_111_777); // Sun, 06 Nov 1994 08:49:37 GMT
    assert_eq!(parse_retry_after("3", now), Some(Duration::from_secs(3)));
    assert_eq!(
        parse_retry_after(" 1.5 ", now),
        Some(Duration::from_millis(1500))
    );
    assert_eq!(
        parse_retry_after("Sun, 06 Nov 1994 08:49:47 GMT", now),
        Some(Duration::from_secs(10))
    );
    // A date in the past is no wait; a huge wait is capped; nonsense is ignored.
    assert_eq!(
        parse_retry_after("Sun, 06 Nov 1994 08:49:00 GMT", now),
        Some(Duration::ZERO)
    );
    assert_eq!(
        parse_retry_after("999999", now),
        Some(agentstar_agent::llm::MAX_RETRY_AFTER)
    );
    assert_eq!(parse_retry_after("soon", SystemTime::now()), None);
    assert_eq!(parse_retry_after("-4", now), None);
}

#[test]
fn giving_up_names_every_kind_of_failure() {
    let url = server(vec![
        (500, "", "{\"error\": \"boom\"}".into()),
        (429, "", "{\"error\": \"slow\"}".into()),
        (200, "", "not json".into()),
        (200, "", "{\"choices\": []}".into()),
    ]);
    let e = complete_with(&config(&url), "s", &[], &[], &|_, _| {}, &|_| {}).expect_err("all fail");
    match &e {
        LlmError::GaveUp {
            attempts, failures, ..
        } => {
            assert_eq!(*attempts, 4);
            let kinds: Vec<&str> = failures.iter().map(|(k, _)| k.as_str()).collect();
            assert_eq!(
                kinds,
                [
                    "HTTP 500",
                    "HTTP 429 (rate limited)",
                    "reply not JSON",
                    "reply without a message"
                ]
            );
        }
        other => panic!("{other:?}"),
    }
    let text = e.to_string();
    assert!(text.contains("4 attempt(s) failed"), "{text}");
}

/// A server that answers every request with a reply body far larger than any model reply:
/// with a declared length of 10 GB, or (`declared` false) no length, streaming until the
/// client hangs up. Counts the requests it saw.
fn huge_reply_server(declared: bool) -> (String, std::sync::Arc<std::sync::atomic::AtomicUsize>) {
    let (listener, url) = support::listen();
    let seen = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let counter = seen.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            counter.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            support::read_request(&stream);
            let length = if declared {
                "content-length: 10000000000\r\n"
            } else {
                ""
            };
            let _ = write!(
                stream,
                "HTTP/1.1 200 OK\r\ncontent-type: application/json\r\n{length}connection: close\r\n\r\n{{\"choices\": [{{\"message\": {{\"content\": \""
            );
            let chunk = vec![b'a'; 1 << 20];
            // Until the client hangs up (at most 10 GB).
            for _ in 0..10_000 {
                if stream.write_all(&chunk).is_err() {
                    break;
                }
            }
        }
    });
    (url, seen)
}

/// Issue 16: replies are read with a bound; one over it is a clear error naming the server
/// and the limit, and it is not retried (another attempt would read as much again).
#[test]
fn a_huge_reply_is_refused_with_its_limit_and_not_retried() {
    for declared in [true, false] {
        let (url, seen) = huge_reply_server(declared);
        let start = std::time::Instant::now();
        let e = complete_with(
            &config(&url),
            "sys",
            &[Message::User(vec![Part::Text("hi".into())])],
            &[],
            &|_, _| {},
            &|_| {},
        )
        .expect_err("over the limit");
        let text = e.to_string();
        assert!(
            matches!(e, LlmError::Fatal(_)),
            "declared {declared}: {e:?}"
        );
        assert!(
            text.contains(&url) && text.contains("larger than the limit of 64 MiB"),
            "{text}"
        );
        assert_eq!(seen.load(std::sync::atomic::Ordering::SeqCst), 1);
        // Well under the 5 s timeout: the limit, not the timeout, ends it.
        assert!(
            start.elapsed() < Duration::from_secs(4),
            "{:?}",
            start.elapsed()
        );
    }
}
