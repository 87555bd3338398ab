//! The model-server replies a model (or a broken proxy) can send, fuzzed from the committed
//! corpus (`fuzz/corpus/reply_*`) with the shared mutator: parsing never panics or hangs.
//! `AGENTSTAR_FUZZ_SECS` lengthens the run (default 6 s).

#[path = "../../../fuzz/harness.rs"]
mod harness;

use agentstar_agent::llm::{parse_reply, Protocol};

#[test]
fn model_replies_never_panic_the_client() {
    harness::fuzz(
        vec![
            (
                "reply_openai",
                Box::new(|b: &[u8]| {
                    let _ = parse_reply(Protocol::OpenAi, &String::from_utf8_lossy(b));
                }) as harness::Run,
            ),
            (
                "reply_anthropic",
                Box::new(|b: &[u8]| {
                    let _ = parse_reply(Protocol::Anthropic, &String::from_utf8_lossy(b));
                }),
            ),
        ],
        6,
    );
}
