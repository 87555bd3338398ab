//! A model server on loopback for the model clients' tests: a listener and the reading of
//! one HTTP request, which each test's server answers in its own way.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::net::{TcpListener, TcpStream};

/// A listener on a free loopback port and its URL (`http://127.0.0.1:PORT`).
pub fn listen() -> (TcpListener, String) {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let url = format!("http://{}", listener.local_addr().expect("addr"));
    (listener, url)
}

/// Reads one request from `stream`: its path and its body (as long as its
/// `content-length` says; empty where the client hung up first).
pub fn read_request(stream: &TcpStream) -> (String, Vec<u8>) {
    let mut r = BufReader::new(stream.try_clone().expect("clone"));
    let mut first = String::new();
    let _ = r.read_line(&mut first);
    let mut len = 0;
    loop {
        let mut l = String::new();
        if r.read_line(&mut l).unwrap_or(0) == 0 || l.trim().is_empty() {
            break;
        }
        if let Some(v) = l.to_ascii_lowercase().strip_prefix("content-length:") {
            len = v.trim().parse().unwrap_or(0);
        }
    }
    let mut body = vec![0; len];
    let _ = r.read_exact(&mut body);
    let path = first.split_whitespace().nth(1).unwrap_or("").to_string();
    (path, body)
}
