//! libFuzzer target: arbitrary bytes into the streaming frame decoders of both directions
//! (split at a point the first byte chooses), every decoded message re-encoded and fed to
//! the device and host link state machines. Must never panic; decoder memory is fixed.
#![no_main]

use controller_core::link::device::DEFAULT_DEVICE_LINK_CONFIG;
use controller_core::link::frame::MAX_ENCODED_LEN;
use controller_core::link::host::DEFAULT_HOST_LINK_CONFIG;
use controller_core::link::kernels::{
    ExampleCommand, ExampleStatus, ExampleTelemetry, ExampleToDevice, ExampleToHost,
};
use controller_core::link::{
    encode, schema_hash, DeviceLink, FrameDecoder, HostLink, MAX_FRAME_LEN,
};
use libfuzzer_sys::fuzz_target;

const HASH: u32 = schema_hash::<ExampleCommand, ExampleTelemetry, ExampleStatus>();

fuzz_target!(|data: &[u8]| {
    let Some((&split, bytes)) = data.split_first() else {
        return;
    };
    let split = usize::from(split).max(1);
    let mut dev_dec = FrameDecoder::new();
    let mut host_dec = FrameDecoder::new();
    let mut dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 10_000).unwrap();
    let mut host = HostLink::<ExampleCommand, 8>::new(&DEFAULT_HOST_LINK_CONFIG, HASH, 0).unwrap();
    let mut buf = [0u8; MAX_FRAME_LEN];
    for (k, chunk) in bytes.chunks(split).enumerate() {
        let now = k as u32 * 7;
        for msg in dev_dec.frames::<ExampleToDevice>(chunk).flatten() {
            // Whatever parsed must encode again.
            assert!(encode(&msg, &mut buf).is_ok());
            let _ = dev.on_frame(msg, now, (k % 5) as u16);
            let _ = dev.poll(now, 3);
        }
        for msg in host_dec.frames::<ExampleToHost>(chunk).flatten() {
            assert!(encode(&msg, &mut buf).is_ok());
            let _ = host.on_frame(msg, now);
            let _ = host.poll(now, |_| {});
        }
        assert!(dev_dec.pending_len() <= MAX_ENCODED_LEN);
        assert!(host_dec.pending_len() <= MAX_ENCODED_LEN);
    }
});
