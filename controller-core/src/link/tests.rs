extern crate std;
use super::*;
#[test]
fn print_golden() {
    let mut out = [0u8; MAX_FRAME_LEN];
    let f: kernels::ExampleToDevice = ToDevice::Command { seq: Seq(300), cmd: kernels::EXAMPLE_COMMAND };
    let n = encode(&f, &mut out).unwrap();
    std::println!("{n} {:02X?}", &out[..n]);
    std::println!("{:#010x}", schema_hash::<(), (), ()>());
    std::println!("{:#010x}", schema_hash::<kernels::ExampleCommand, kernels::ExampleTelemetry, kernels::ExampleStatus>());
}
