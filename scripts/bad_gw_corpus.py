"""Writes compiler/tests/corpus/*.gw: a corpus of wrong .gw programs, each
with one kind of mistake, for compiler/tests/corpus.rs (every one must be
a spanned diagnostic with a help line, snapshot-tested, and never a panic).

    python3 scripts/bad_gw_corpus.py

Existing files are rewritten; files of cases no longer listed are removed.
"""

import os
import re

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "compiler", "tests", "corpus")

GRID = "grid f = frequencies(from: 20 Hz, to: 512 Hz, step: 0.5 Hz)"
PARAMS = "param mc: Msun = 30.0 in 1.0..100.0\n    param tc: s = 0.0 in -0.1..0.1\n    param x = 0.5"


def scene(body, pre="", name="s", grid=GRID, params=PARAMS):
    lines = [l for l in (grid, params) if l] + body.strip("\n").split("\n")
    return pre + f"scene {name} {{\n" + "\n".join("    " + l.strip() if not l.startswith("    ") else l for l in "\n".join(lines).split("\n")) + "\n}\n"


CASES = []


def case(category, slug, text):
    CASES.append((category, slug, text))


# --- syntax -----------------------------------------------------------------
S = "syntax"
case(S, "missing_closing_brace", scene("output y = mc").rstrip("}\n") + "\n")
case(S, "param_without_default_expression", scene("param z =\noutput y = mc"))
case(S, "two_operators_in_a_row", scene("let a = x * * 2.0\noutput y = a"))
case(S, "unclosed_parenthesis", scene("output y = (x + 1.0"))
case(S, "stray_closing_brace_at_top_level", "}\n" + scene("output y = x"))
case(S, "scene_without_a_name", "scene {\n    output y = 1.0\n}\n")
case(S, "scene_without_braces", "scene s\n    output y = 1.0\n")
case(S, "name_starting_with_a_digit", scene("param 3z = 1.0\noutput y = x"))
case(S, "let_without_a_name", scene("let = 2.0\noutput y = x"))
case(S, "output_without_equals", scene("output y 2.0"))
case(S, "missing_comma_between_arguments", scene("output y = x", grid="grid f = frequencies(from: 20 Hz to: 512 Hz, step: 0.5 Hz)"))
case(S, "unexpected_character", scene("output y = x $ 2.0"))
case(S, "unclosed_module_parameter_list", "module m(a {\n    a\n}\n" + scene("output y = m(x)"))
case(S, "unclosed_import_list", "use std::taylorf2::{tf2_strain\n" + scene("output y = x"))
case(S, "incomplete_import_path", "use std::\n" + scene("output y = x"))
case(S, "bounds_without_upper_end", scene("param z = 1.0 in 0.0..\noutput y = z"))
case(S, "bounds_without_lower_end", scene("param z = 1.0 in ..2.0\noutput y = z"))
case(S, "if_without_else", scene("output y = if x > 0.0 { 1.0 }"))
case(S, "if_without_condition", scene("output y = if { 1.0 } else { 2.0 }"))
case(S, "number_with_two_points", scene("let a = 1.0.2\noutput y = a"))
case(S, "exponent_without_digits", scene("let a = 1e\noutput y = a"))
case(S, "power_without_exponent", scene("output y = x ^"))
case(S, "unclosed_grid_bracket_in_type", scene("input d: complex[f s\noutput y = x"))
case(S, "grad_list_without_comma", scene("output y = mc * tc\ngrad y wrt [mc tc]"))
case(S, "setting_without_colon", scene("precision f64\noutput y = x"))
case(S, "knob_without_a_name", scene("knob = 3\noutput y = x"))
case(S, "keyword_as_a_name", scene("let scene = 1.0\noutput y = x"))
case(S, "learned_without_a_name", "learned (x) {\n    x\n}\n" + scene("output y = x"))
case(S, "argument_list_starting_with_a_comma", scene("output y = sqrt(, x)"))
case(S, "doubled_imaginary_suffix", scene("output y = 2.5ii"))
case(S, "unclosed_unit_bracket", scene("let a = 3 [m/s\noutput y = a"))
case(S, "statement_outside_any_scene", "let a = 1.0\n" + scene("output y = x"))
case(S, "empty_parentheses_expression", scene("output y = () + x"))
case(S, "comparison_chain", scene("output y = if 0.0 < x < 1.0 { 1.0 } else { 0.0 }"))
case(S, "missing_operand_before_operator", scene("output y = * x"))
case(S, "unclosed_if_block", scene("output y = if x > 0.0 { 1.0 else { 2.0 }"))
case(S, "module_without_result", "module m(a) {\n    let b = a\n}\n" + scene("output y = m(x)"))
case(S, "named_argument_without_value", scene("output y = x", grid="grid f = frequencies(from:, to: 512 Hz, step: 0.5 Hz)"))
case(S, "garbage_after_scene", scene("output y = x") + "@@@\n")

# --- names ------------------------------------------------------------------
N = "names"
case(N, "unknown_name", scene("output y = mc + undefined_name"))
case(N, "misspelt_param", scene("output y = mcc * 2.0"))
case(N, "unknown_function", scene("output y = sqr(x)"))
case(N, "misspelt_builtin", scene("output y = sine(x)"))
case(N, "param_declared_twice", scene("param x = 1.0\noutput y = x"))
case(N, "let_defined_twice", scene("let a = 1.0\nlet a = 2.0\noutput y = a"))
case(N, "output_defined_twice", scene("output y = x\noutput y = mc"))
case(N, "let_shadows_a_param", scene("let mc = 2.0 Msun\noutput y = mc"))
case(N, "unknown_stdlib_module", "use std::taylorf2::{tf2_nope}\n" + scene("output y = x"))
case(N, "unknown_stdlib_file", "use std::nothing::{thing}\n" + scene("output y = x"))
case(N, "unknown_grid_in_input_type", scene("input d: complex[g] s\noutput y = x"))
case(N, "spectrum_of_an_unknown_grid", scene("grid s2 = spectrum(t)\noutput y = x"))
case(N, "grad_of_an_unknown_output", scene("output y = x * x\ngrad nope wrt [x]"))
case(N, "grad_wrt_a_misspelt_param", scene("output y = x * x\ngrad y wrt [xx]"))
case(N, "grad_wrt_an_input", scene("input d: real = 1.0\noutput y = x * d\ngrad y wrt [d]"))
case(N, "scene_defined_twice", scene("output y = x") + scene("output y = x"))
case(N, "module_defined_twice", "module m(a) {\n    a\n}\nmodule m(a) {\n    2.0 * a\n}\n" + scene("output y = m(x)"))
case(N, "module_called_with_too_many_arguments", "module m(a) {\n    a\n}\n" + scene("output y = m(x, x)"))
case(N, "module_called_with_too_few_arguments", "module m(a, b) {\n    a * b\n}\n" + scene("output y = m(x)"))
case(N, "unknown_named_argument", scene("output y = x", grid="grid f = frequencies(from: 20 Hz, to: 512 Hz, stride: 0.5 Hz)"))
case(N, "missing_named_argument", scene("output y = x", grid="grid f = frequencies(from: 20 Hz, to: 512 Hz)"))
case(N, "param_called_as_a_function", scene("output y = x(2.0)"))
case(N, "grid_defined_twice", scene("grid f = frequencies(from: 10 Hz, to: 20 Hz, step: 1 Hz)\noutput y = x"))
case(N, "constant_in_the_wrong_case", scene("output y = PI * x"))
case(N, "named_argument_given_twice", scene("output y = x", grid="grid f = frequencies(from: 20 Hz, from: 30 Hz, to: 512 Hz, step: 0.5 Hz)"))
case(N, "module_name_used_as_a_value", "module m(a) {\n    a\n}\n" + scene("output y = m + 1.0"))
case(N, "unknown_module_argument_name", "module m(a, b: s = 1 s) {\n    a * b\n}\n" + scene("output y = m(x, c: 2 s)"))
case(N, "grad_wrt_an_unknown_learned_component", scene("output y = x * x\ngrad y wrt cnn2"))
case(N, "grid_name_used_as_a_scalar_param", scene("param f = 1.0\noutput y = x"))
case(N, "import_of_a_name_twice", "use std::detector::{inner, inner}\n" + scene("output y = x"))
case(N, "scene_used_as_a_module", scene("output y = x", name="a") + scene("output y = a(x)", name="b"))
case(N, "output_used_before_any_definition_of_it", scene("output y = z"))
case(N, "unknown_grid_passed_to_spacing", scene("output y = spacing(g)"))
case(N, "input_declared_twice", scene("input d: real = 1.0\ninput d: real = 2.0\noutput y = d"))
case(N, "learned_defined_twice", "learned l(a) {\n    weight w: [2] = zeros\n    a\n}\nlearned l(a) {\n    weight w: [2] = zeros\n    a\n}\n" + scene("output y = x"))

# --- units ------------------------------------------------------------------
U = "units"
case(U, "msun_plus_seconds", scene("output y = mc + tc"))
case(U, "hertz_plus_seconds", scene("output y = sum(f) + tc"))
case(U, "unknown_unit_in_a_param", scene("param z: parsec = 1.0\noutput y = z"))
case(U, "unknown_unit_in_a_literal", scene("output y = 3 furlongs"))
case(U, "declared_output_unit_differs", scene("output y: s = mc"))
case(U, "sine_of_a_mass", scene("output y = sin(mc)"))
case(U, "exp_of_a_time", scene("output y = exp(tc)"))
case(U, "log_of_a_time", scene("output y = log(tc + 1 s)"))
case(U, "dimensioned_exponent", scene("output y = 2.0 ^ mc"))
case(U, "varying_exponent_of_a_dimensioned_base", scene("output y = mc ^ x"))
case(U, "comparison_of_mass_and_time", scene("output y = if mc > tc { 1.0 } else { 0.0 }"))
case(U, "grid_step_in_seconds", scene("output y = x", grid="grid f = frequencies(from: 20 Hz, to: 512 Hz, step: 0.5 s)"))
case(U, "sample_rate_in_seconds", scene("output y = x", grid="grid t = times(rate: 1024 s, duration: 1 s)"))
case(U, "input_default_in_another_unit", scene("input d: complex[f] s = 1.0 Msun\noutput y = x"))
case(U, "module_argument_in_another_unit", "module m(a: Hz) {\n    a\n}\n" + scene("output y = m(tc)"))
case(U, "if_branches_in_different_units", scene("output y = if x > 0.0 { mc } else { tc }"))
case(U, "max_of_mass_and_time", scene("output y = max(mc, tc)"))
case(U, "atan2_of_different_units", scene("output y = atan2(mc, tc)"))
case(U, "knob_in_the_wrong_unit_for_a_step", scene("knob df = 0.5 s\noutput y = x", grid="grid f = frequencies(from: 20 Hz, to: 512 Hz, step: df)"))
case(U, "clamp_with_mixed_units", scene("output y = clamp(tc, 0.0 s, 1.0 Msun)"))
case(U, "cis_of_a_frequency", scene("output y = sum(re(cis(f)))"))
case(U, "square_root_plus_mass", scene("output y = sqrt(mc) + mc"))
case(U, "unit_exponent_divided_by_zero", scene("param z: s^(1/0) = 1.0\noutput y = z"))
case(U, "speed_plus_frequency", scene("output y = 3 [m/s] + 1 Hz"))
case(U, "unknown_unit_in_an_input_type", scene("input d: complex[f] furlong = 0.0\noutput y = x"))
case(U, "tanh_of_a_distance", scene("output y = tanh(400 Mpc)"))
case(U, "minimum_over_mixed_units", scene("output y = min(mc, 1 Hz)"))
case(U, "subtracting_hertz_from_a_time_grid", scene("output y = x", grid="grid t = times(rate: 1024 Hz, duration: 1 s)\n    let z = t - 1 Hz"))
case(U, "duration_in_hertz", scene("output y = x", grid="grid t = times(rate: 1024 Hz, duration: 1 Hz)"))
case(U, "select_of_mixed_units", scene("output y = select(x > 0.0, mc, tc)"))
case(U, "masked_div_result_in_the_wrong_output_unit", scene("output y: s = masked_div(mc, x)"))
case(U, "abs_of_time_compared_with_frequency", scene("output y = if abs(tc) < 1 Hz { 1.0 } else { 0.0 }"))

# --- shapes and element kinds -------------------------------------------------
H = "shapes"
TWO = GRID + "\n    grid g = frequencies(from: 10 Hz, to: 30 Hz, step: 1 Hz)"
TIME = "grid t = times(rate: 256 Hz, duration: 1 s)"
case(H, "arrays_on_two_grids", scene("output y = sum(f + g)", grid=TWO))
case(H, "max_of_arrays_on_two_grids", scene("output y = sum(max(f, g))", grid=TWO))
case(H, "rfft_onto_a_grid_that_is_not_its_spectrum", scene("output y = sum(abs2(rfft(sin(t / 1 s), f)))", grid=TIME + "\n    " + GRID))
case(H, "irfft_onto_a_frequency_grid", scene("output y = sum(irfft(cis(f / 1 Hz), f))"))
case(H, "spectrum_of_a_frequency_grid", scene("grid s2 = spectrum(f)\noutput y = x"))
case(H, "grad_of_an_array_output", scene("output h = f * mc / 1 Hz\ngrad h wrt [mc]"))
case(H, "grad_of_a_complex_output", scene("output h = sum(cis(f / 1 Hz)) * x\ngrad h wrt [x]"))
case(H, "real_input_with_a_complex_default", scene("input d: real[f] = 1.0i\noutput y = x"))
case(H, "complex_condition", scene("output y = sum(if cis(f / 1 Hz) > 0.0 { 1.0 } else { 0.0 })"))
case(H, "boolean_in_arithmetic", scene("output y = (x > 1.0) + 1.0"))
case(H, "clamp_of_a_complex_value", scene("output y = re(clamp(2.0i, 0.0, 1.0))"))
case(H, "sum_of_a_scalar", scene("output y = sum(x)"))
case(H, "mean_of_a_constant", scene("output y = mean(3.0)"))
case(H, "spacing_of_a_param", scene("output y = spacing(mc)"))
case(H, "builtin_arity", scene("output y = re(x, x)"))
case(H, "select_without_a_boolean", scene("output y = select(x, 1.0, 2.0)"))
case(H, "complex_output_declared_real_in_a_comparison", scene("output y = if 1.0i < x { 1.0 } else { 2.0 }"))
case(H, "array_param_default", scene("param z = sum(f)\noutput y = z"))
case(H, "array_assigned_to_a_scalar_input_default", scene("input d: real = f / 1 Hz\noutput y = d"))
case(H, "scalar_input_with_an_array_default", scene("input d: real = sin(f / 1 Hz)\noutput y = x"))
case(H, "atan2_of_complex", scene("output y = atan2(1.0i, x)"))
case(H, "log_of_a_complex_value", scene("output y = re(log(1.0i))"))
case(H, "masked_div_of_complex_by_complex", scene("output y = re(masked_div(1.0i, 2.0i))"))
case(H, "array_output_of_a_module_added_to_another_grid", "module m(a: Hz) {\n    a / 1 Hz\n}\n" + scene("output y = sum(m(f) + m(g))", grid=TWO))
case(H, "max_with_three_arguments", scene("output y = max(x, x, x)"))
case(H, "abs2_of_a_boolean", scene("output y = abs2(x > 0.0)"))

# --- grids ------------------------------------------------------------------
G = "grids"
def grid_case(slug, grid):
    case(G, slug, scene("output y = x", grid=grid))
grid_case("step_zero", "grid f = frequencies(from: 20 Hz, to: 512 Hz, step: 0 Hz)")
grid_case("negative_step", "grid f = frequencies(from: 20 Hz, to: 512 Hz, step: -0.5 Hz)")
grid_case("from_above_to", "grid f = frequencies(from: 512 Hz, to: 20 Hz, step: 0.5 Hz)")
grid_case("huge_frequency_grid", "grid f = frequencies(from: 0 Hz, to: 1e9 Hz, step: 1e-3 Hz)")
grid_case("zero_duration", "grid t = times(rate: 1024 Hz, duration: 0 s)")
grid_case("negative_rate", "grid t = times(rate: -1024 Hz, duration: 1 s)")
grid_case("index_of_zero", "grid k = index(0)")
grid_case("index_of_a_negative_number", "grid k = index(-3)")
grid_case("index_of_a_fraction", "grid k = index(2.5)")
grid_case("dimensionless_frequencies", "grid f = frequencies(from: 20, to: 512, step: 0.5)")
grid_case("grid_from_a_param", "param fmin: Hz = 20.0\n    grid f = frequencies(from: fmin, to: 512 Hz, step: 0.5 Hz)")
grid_case("times_without_a_duration", "grid t = times(rate: 1024 Hz)")
grid_case("grid_from_a_number", "grid f = 3.0")
grid_case("huge_time_grid", "grid t = times(rate: 1e12 Hz, duration: 1e6 s)")
grid_case("huge_index_grid", "grid k = index(1e12)")
grid_case("unknown_grid_constructor", "grid f = linspace(0 Hz, 1 Hz, 10)")
grid_case("infinite_upper_frequency", "grid f = frequencies(from: 20 Hz, to: 1e400 Hz, step: 0.5 Hz)")
grid_case("nan_step", "grid f = frequencies(from: 20 Hz, to: 512 Hz, step: 0 Hz / 0.0)")
grid_case("rate_not_a_multiple_of_duration", "grid t = times(rate: 3 Hz, duration: 0.1 s)")
grid_case("spectrum_of_itself", "grid s2 = spectrum(s2)")

# --- knobs ------------------------------------------------------------------
K = "knobs"
case(K, "knob_from_a_param", scene("knob k = x\noutput y = k"))
case(K, "knobs_in_a_cycle", scene("knob a = b\nknob b = a\noutput y = a"))
case(K, "knob_defined_twice", scene("knob k = 1\nknob k = 2\noutput y = k"))
case(K, "knob_from_an_array", scene("knob k = sum(f)\noutput y = k"))
case(K, "knob_with_the_name_of_a_param", scene("knob x = 1.0\noutput y = x"))
case(K, "knob_that_is_not_a_number", scene("knob k = 0.0 / 0.0\noutput y = k"))
case(K, "knob_written_as_a_string", scene('knob k = "fast"\noutput y = k'))
case(K, "complex_knob_as_a_step", scene("knob df = 2.0i\noutput y = x", grid="grid f = frequencies(from: 20 Hz, to: 512 Hz, step: df)"))
case(K, "knob_making_a_zero_step", scene("knob df = 0 Hz\noutput y = x", grid="grid f = frequencies(from: 20 Hz, to: 512 Hz, step: df)"))
case(K, "knob_from_an_input", scene("input d: real = 1.0\nknob k = d\noutput y = k"))
case(K, "knob_from_a_let", scene("let a = 2.0\nknob k = a\noutput y = k"))
case(K, "knob_with_a_varying_exponent", scene("knob k = 2.0 ^ x\noutput y = k"))
case(K, "knob_with_an_unknown_unit", scene("knob k = 3 furlongs\noutput y = x"))
case(K, "knob_referring_to_itself", scene("knob k = k + 1\noutput y = k"))
case(K, "knob_from_a_grid_spacing_of_an_unknown_grid", scene("knob k = spacing(g)\noutput y = k"))
case(K, "knob_overflowing_to_infinity", scene("knob k = 1e308 * 10.0\noutput y = x * k"))

# --- settings ---------------------------------------------------------------
T = "settings"
case(T, "precision_f16", scene("precision: f16\noutput y = x"))
case(T, "unknown_math_mode", scene("math: approximate\noutput y = x"))
case(T, "negative_multiband_tolerance", scene("multiband: -1\noutput y = x"))
case(T, "multiband_tolerance_that_is_not_a_number", scene("multiband: banana\noutput y = x"))
case(T, "one_relative_binning_bin", scene("relative_binning: 1\noutput y = x"))
case(T, "too_many_relative_binning_bins", scene("relative_binning: 1000000000\noutput y = x"))
case(T, "precision_set_twice", scene("precision: f64\nprecision: f32\noutput y = x"))
case(T, "setting_inside_a_module", "module m(a) {\n    precision: f32\n    a\n}\n" + scene("output y = m(x)"))
case(T, "unknown_setting", scene("speed: fast\noutput y = x"))
case(T, "relative_binning_of_a_fraction", scene("relative_binning: 2.5\noutput y = x"))
case(T, "multiband_of_zero", scene("multiband: 0\noutput y = x"))
case(T, "math_mode_given_as_a_number", scene("math: 3\noutput y = x"))

# --- learned components -------------------------------------------------------
L = "learned"
TG = "grid t = times(rate: 256 Hz, duration: 1 s)\n    grid classes = index(2)"
LP = "input v: real[t] = 0.0\n    input label: real[classes] = 0.0"


def learned(slug, body, use, extra_scene="", grid=TG):
    text = "use std::nn::{relu, cross_entropy}\n\nlearned net(v) {\n" + "\n".join("    " + l for l in body.strip().split("\n")) + "\n}\n\n"
    text += scene(LP + "\n    " + use + ("\n    " + extra_scene if extra_scene else ""), grid=grid, params="")
    case(L, slug, text)


DENSE_OK = "weight w: [2, 256] = glorot(seed: 1)\nweight b: [2] = zeros\ndense(v, w, b)"
learned("dense_weight_of_the_wrong_shape", "weight w: [3, 256] = glorot(seed: 1)\nweight b: [2] = zeros\ndense(v, w, b)", "output loss = cross_entropy(net(v), label)\ngrad loss wrt net")
learned("conv_kernel_longer_than_its_input", "weight k: [2, 1, 300] = he(seed: 1)\nweight b: [2] = zeros\nmax_pool(conv1d(v, k, b), 2)", "output loss = sum(net(v))")
learned("conv_with_the_wrong_channels", "weight k: [2, 3, 8] = he(seed: 1)\nweight b: [2] = zeros\nconv1d(v, k, b)", "output loss = sum(net(v))")
case(L, "weight_in_a_plain_module", "module m(a) {\n    weight w: [2] = zeros\n    a\n}\n" + scene("output y = m(x)"))
learned("unknown_initialiser", "weight w: [2, 256] = ones_ish\nweight b: [2] = zeros\ndense(v, w, b)", "output loss = cross_entropy(net(v), label)")
learned("negative_weight_dimension", "weight w: [2, -256] = glorot(seed: 1)\nweight b: [2] = zeros\ndense(v, w, b)", "output loss = cross_entropy(net(v), label)")
learned("zero_weight_dimension", "weight w: [0, 256] = glorot(seed: 1)\nweight b: [0] = zeros\ndense(v, w, b)", "output loss = sum(net(v))")
learned("gradient_wrt_an_unused_component", DENSE_OK, "output loss = sum(label)\ngrad loss wrt net")
learned("layer_on_a_value_with_units", DENSE_OK, "output loss = sum(net(t))")
learned("max_pool_of_zero", "weight b: [2] = zeros\nmax_pool(v, 0)", "output loss = sum(net(v))")
learned("max_pool_wider_than_its_input", "weight b: [2] = zeros\nmax_pool(v, 1000)", "output loss = sum(net(v))")
learned("dense_on_a_scalar", "weight w: [2, 1] = glorot(seed: 1)\nweight b: [2] = zeros\ndense(1.0, w, b)", "output loss = sum(net(v))")
learned("learned_called_with_two_arguments", DENSE_OK, "output loss = sum(net(v, v))")
learned("weight_declared_twice", "weight w: [2, 256] = glorot(seed: 1)\nweight w: [2, 256] = glorot(seed: 2)\nweight b: [2] = zeros\ndense(v, w, b)", "output loss = sum(net(v))")
learned("reshape_to_another_size", "weight b: [2] = zeros\nreshape(v, [3, 100])", "output loss = sum(net(v))")
learned("upsample_by_zero", "weight b: [2] = zeros\nupsample(v, 0)", "output loss = sum(net(v))")
learned("dropout_rate_above_one", "weight w: [2, 256] = glorot(seed: 1)\nweight b: [2] = zeros\ndense(dropout(v, 1.5), w, b)", "output loss = sum(net(v))")
learned("negative_padding", "weight k: [2, 1, 8] = he(seed: 1)\nweight b: [2] = zeros\nconv1d(v, k, b, padding: -4)", "output loss = sum(net(v))")
learned("grad_wrt_an_unknown_component", DENSE_OK, "output loss = cross_entropy(net(v), label)\ngrad loss wrt nett")
learned("weight_without_a_shape", "weight w = zeros\nweight b: [2] = zeros\ndense(v, w, b)", "output loss = sum(net(v))")
learned("huge_weight", "weight w: [100000, 100000] = zeros\nweight b: [100000] = zeros\ndense(v, w, b)", "output loss = sum(net(v))")
learned("dense_bias_of_the_wrong_length", "weight w: [2, 256] = glorot(seed: 1)\nweight b: [3] = zeros\ndense(v, w, b)", "output loss = sum(net(v))")
learned("glorot_without_a_seed_value", "weight w: [2, 256] = glorot(seed: x)\nweight b: [2] = zeros\ndense(v, w, b)", "output loss = sum(net(v))")
learned("cross_entropy_of_mismatched_grids", DENSE_OK, "output loss = cross_entropy(net(v), v)")

# --- cycles ----------------------------------------------------------------
C = "cycles"
case(C, "two_lets_in_a_cycle", scene("let a = b\nlet b = a\noutput y = a"))
case(C, "module_calling_itself", "module m(a) {\n    m(a) + 1.0\n}\n" + scene("output y = m(x)"))
case(C, "modules_calling_each_other", "module m(a) {\n    n(a)\n}\nmodule n(a) {\n    m(a)\n}\n" + scene("output y = m(x)"))
case(C, "three_lets_in_a_cycle", scene("let a = c + 1.0\nlet b = a * 2.0\nlet c = b - x\noutput y = a"))
case(C, "let_defined_by_itself", scene("let a = a + 1.0\noutput y = a"))
case(C, "input_default_referring_to_itself", scene("input d: real = d\noutput y = d"))
case(C, "module_default_argument_referring_to_the_module", "module m(a, b = m(1.0)) {\n    a * b\n}\n" + scene("output y = m(x)"))
case(C, "output_defined_by_itself", scene("output y = y + x"))
case(C, "learned_calling_itself", "learned l(a) {\n    weight w: [2] = zeros\n    l(a)\n}\n" + scene("output y = l(x)"))
case(C, "let_and_output_in_a_cycle", scene("let a = y\noutput y = a"))

# --- modules ----------------------------------------------------------------
M = "modules"
case(M, "param_inside_a_module", "module m(a) {\n    param b = 1.0\n    a * b\n}\n" + scene("output y = m(x)"))
case(M, "output_inside_a_module", "module m(a) {\n    output z = a\n    a\n}\n" + scene("output y = m(x)"))
case(M, "grid_inside_a_module", "module m(a) {\n    grid g = index(3)\n    a\n}\n" + scene("output y = m(x)"))
case(M, "module_using_a_scene_name", "module m(a) {\n    a * mc\n}\n" + scene("output y = m(x)"))
case(M, "module_with_a_repeated_argument", "module m(a, a) {\n    a\n}\n" + scene("output y = m(x, x)"))
case(M, "module_argument_default_in_the_wrong_unit", "module m(a, b: s = 1 Hz) {\n    a * b\n}\n" + scene("output y = m(x)"))
case(M, "scene_inside_a_module", "module m(a) {\n    scene inner {\n        output z = 1.0\n    }\n    a\n}\n" + scene("output y = m(x)"))
case(M, "import_inside_a_scene", scene("use std::detector::{inner}\noutput y = x"))
case(M, "stdlib_module_with_the_wrong_arguments", "use std::detector::{inner}\n" + scene("output y = inner(f, f)"))
case(M, "module_result_of_the_wrong_unit_for_an_output", "module m(a: s) {\n    a\n}\n" + scene("output y: Hz = m(tc)"))
case(M, "glitch_module_with_a_missing_argument", "use std::glitch::{blip}\n" + scene("output y = sum(blip(t, 0.5 s, 100 Hz))", grid="grid t = times(rate: 1024 Hz, duration: 1 s)"))

# --- limits ----------------------------------------------------------------
X = "limits"
case(X, "deeply_nested_parentheses", scene("output y = " + "(" * 3000 + "x + nope" + ")" * 3000))
case(X, "deeply_nested_unary_minus", scene("output y = " + "-" * 3000 + "nope"))
case(X, "very_long_sum", scene("output y = " + " + ".join(["x"] * 5000) + " + nope"))
case(X, "number_overflowing_to_infinity", scene("output y = x * 1e400"))
case(X, "very_long_unknown_name", scene("output y = " + "a" * 10000))
case(X, "deeply_nested_if", scene("output y = " + "if x > 0.0 { " * 500 + "nope" + " } else { 0.0 }" * 500))
case(X, "deeply_nested_calls", scene("output y = " + "sqrt(" * 2000 + "nope" + ")" * 2000))
case(X, "many_params_one_misspelt", scene("\n".join(f"param p{i} = {i}.0" for i in range(500)) + "\noutput y = " + " + ".join(f"p{i}" for i in range(500)) + " + p500"))
case(X, "deeply_nested_module_calls", "".join(f"module m{i}(a) {{\n    m{i+1}(a) + 1.0\n}}\n" for i in range(300)) + "module m300(a) {\n    nope\n}\n" + scene("output y = m0(x)"))
case(X, "huge_number_of_grid_points_in_an_index", scene("output y = x", grid="grid k = index(4294967297)"))


def slugify(s):
    return re.sub(r"[^a-z0-9_]", "_", s.lower())


def main():
    os.makedirs(OUT, exist_ok=True)
    names = set()
    for category, slug, text in CASES:
        name = f"{category}__{slugify(slug)}.gw"
        assert name not in names, name
        names.add(name)
        with open(os.path.join(OUT, name), "w") as f:
            f.write(text)
    for old in os.listdir(OUT):
        if old.endswith(".gw") and old not in names:
            os.remove(os.path.join(OUT, old))
    print(f"wrote {len(names)} files to {os.path.normpath(OUT)}")


if __name__ == "__main__":
    main()
