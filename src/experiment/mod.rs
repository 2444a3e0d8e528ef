//! Experiments of the glitch study (issue #7): classifiers of the whitened
//! glitch segments of `gwml::runtime::synth::glitches`.

pub mod rules;
