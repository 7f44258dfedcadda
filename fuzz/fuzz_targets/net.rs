//! Untrusted bytes from the network: a hello, then messages whose payloads are run as
//! instruction batches by a streaming processor (frames are not rendered here), plus every
//! server-message decoder a client uses.
#![no_main]
use libfuzzer_sys::fuzz_target;
use lucent_engine::{Processor, Step};
use lucent_net::protocol::{self, Chunk, Done, FrameHeader, Hello, Welcome, WireError, HELLO_LEN};

fuzz_target!(|data: &[u8]| {
    if data.len() >= HELLO_LEN {
        let mut h = [0u8; HELLO_LEN];
        h.copy_from_slice(&data[..HELLO_LEN]);
        let _ = Hello::parse(&h);
    }
    let _ = (WireError::decode(data), Done::decode(data), FrameHeader::decode(data), Welcome::decode(data), Chunk::decode(data));
    let mut p = Processor::new(Vec::new(), lucent_isa::CameraTable::Final).expect("empty program");
    let mut r = data.get(HELLO_LEN.min(data.len())..).unwrap_or(&[]);
    while let Ok(Some((_, payload))) = protocol::read_message(&mut r, 4096) {
        let words = protocol::words_from_bytes(&payload);
        if lucent_isa::decode(&words).is_ok() && p.push(&words).is_ok() {
            for _ in 0..64 {
                match p.run_to_frame(10_000) {
                    Step::Frame => {}
                    Step::Busy => p.stop(),
                    _ => break,
                }
            }
        }
    }
});
