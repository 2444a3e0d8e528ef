//! Embedding gwml in a Rust program: compile a model, bind params, run the
//! fused forward+gradient kernel, and use the gradient.
//!
//!     cargo run --example embed

fn main() -> Result<(), gwml::Error> {
    // A model from a string: a damped sinusoid and its energy.
    let model = gwml::compile_str(
        "ringdown.gw",
        "scene ringdown {
            grid t = times(rate: 4096 Hz, duration: 0.25 s)
            param f0: Hz = 250.0 in 20.0..1000.0
            param tau: s = 0.004 in 0.0001..0.1
            let h = exp(-t / tau) * sin(2.0 * pi * f0 * t)
            output energy = sum(h * h) / 4096 Hz
            grad energy wrt [f0, tau]
        }",
    )?;
    let scene = model.scene(None)?;
    let out = scene.bind().value_and_grad()?;
    println!(
        "ringdown: energy {:.6e} s, d/df0 {:.3e} s/Hz, d/dtau {:.3e}",
        out.scalar("energy")?,
        out.grad("energy", "f0")?,
        out.grad("energy", "tau")?
    );

    // The chirp example: fit the coalescence phase by gradient descent.
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/chirp_fit.gw");
    let model = gwml::compile_file(path)?;
    let scene = model.scene(Some("chirp_fit"))?;
    let mut run = scene.bind();
    run.param("mc", 30.0)?.param("tc", 0.002)?;
    let mut phic = 0.0;
    for step in 0..=40 {
        run.param("phic", phic)?;
        let out = run.value_and_grad()?;
        if step % 10 == 0 {
            println!("step {step:2}: phic {phic:.6} loss {:.6e}", out.scalar("loss")?);
        }
        phic -= 0.002 * out.grad("loss", "phic")?;
    }
    println!("true phic is 0.3");
    Ok(())
}
