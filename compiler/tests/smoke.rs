use gwml_compiler::{interp, Program};
#[test]
fn smoke() {
    let src = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/chirp_fit.gw")).unwrap();
    let p = match Program::parse("chirp_fit.gw", &src) { Ok(p) => p, Err(e) => panic!("{}", e) };
    let pl = p.pipeline(None, Default::default()).unwrap();
    println!("{}", pl.optimized);
    println!("{:?}", pl.stats);
    let f = &pl.optimized;
    let d = f.inputs[0].default.clone().unwrap();
    let r = interp::interpret(f, &[28.0, 0.0, 0.0], &[d]);
    println!("loss {:?} grad {:?}", r.output(f, "loss"), r.grad(f, "loss", "mc"));
}
