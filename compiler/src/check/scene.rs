//! Scene lowering: a scene's declarations, settings (`precision`,
//! `math`), knobs and gradient requests, in the order the IR needs them.

use super::*;

impl<'a> Checker<'a> {
    /// Checks `scene` and lowers it to IR, with `overrides` replacing the
    /// values of its knobs.
    pub fn lower_scene(mut self, scene: &'a SceneDef, overrides: &'a [KnobOverride]) -> SceneResult {
        let mut func = ir::Function { name: scene.name.node.clone(), ..Default::default() };
        let mut scope = Scope::new(ScopeKind::Scene);
        let mut declared: HashMap<String, Span> = HashMap::new();
        let mut knobs: HashMap<String, Span> = HashMap::new();
        for st in &scene.stmts {
            let name = match st {
                SceneStmt::Grid { name, .. } | SceneStmt::Input { name, .. } => Some(name),
                SceneStmt::Param(p) => Some(&p.name),
                SceneStmt::Let(l) | SceneStmt::Output(l) | SceneStmt::Knob(l) => Some(&l.name),
                _ => None,
            };
            if let Some(n) = name {
                if let Some(prev) = declared.insert(n.node.clone(), n.span) {
                    self.error(
                        Diagnostic::error(n.span, format!("`{}` is declared twice in scene `{}`", n.node, scene.name.node))
                            .with_secondary(prev, "first declared here")
                            .with_help("rename one of them"),
                    );
                }
            }
            if let SceneStmt::Setting { name, value } = st {
                if let Some(prev) = knobs.insert(name.node.clone(), name.span) {
                    self.error(
                        Diagnostic::error(name.span, format!("knob `{}` is set twice", name.node))
                            .with_secondary(prev, "first set here")
                            .with_help("keep one setting"),
                    );
                }
                let setting_error = |e: ir::UnknownSetting| {
                    Diagnostic::error(value.span, e.to_string()).with_help(format!("write `{}:` followed by {}", name.node, e.help))
                };
                match name.node.as_str() {
                    "precision" => match value.node.parse() {
                        Ok(p) => func.precision = p,
                        Err(e) => self.error(setting_error(e)),
                    },
                    "math" => match value.node.parse() {
                        Ok(m) => func.math = m,
                        Err(e) => self.error(setting_error(e)),
                    },
                    "multiband" => match value.node.parse() {
                        Ok(m) => func.multiband = m,
                        Err(e) => self.error(setting_error(e)),
                    },
                    "relative_binning" => match value.node.parse() {
                        Ok(r) => func.relative_binning = r,
                        Err(e) => self.error(setting_error(e)),
                    },
                    other => {
                        let mut d = Diagnostic::error(name.span, format!("unknown scene setting `{other}`")).with_label("not a knob");
                        d = match did_you_mean(other, ["precision", "math", "multiband", "relative_binning"]) {
                            Some(s) => d.with_help(format!("did you mean `{s}`?")),
                            None => d.with_help(
                                "the settings are `precision: f64 | f32 | mixed`, `math: exact | fast | fastest`, `multiband: off | TOLERANCE` and `relative_binning: off | BINS`",
                            ),
                        };
                        self.error(d);
                    }
                }
            }
        }
        self.scene_knobs(scene, overrides);
        func.knobs = scene
            .stmts
            .iter()
            .filter_map(|st| match st {
                SceneStmt::Knob(k) => self.knobs.get(&k.name.node).map(|&(value, dim)| ir::KnobValue {
                    name: k.name.node.clone(),
                    value,
                    unit: dim.to_string(),
                }),
                _ => None,
            })
            .collect();
        let mut b = Builder::new(func, false);
        // Grids first: inputs' types name them.
        for st in &scene.stmts {
            if let SceneStmt::Grid { name, def } = st {
                let Some(grid) = self.grid_def(name, def, &scope.grids, &b.func.grids) else {
                    scope.poisoned.insert(name.node.clone());
                    continue;
                };
                {
                    let id = ir::GridId(b.func.grids.len() as u32);
                    b.func.grids.push(grid);
                    scope.grids.insert(name.node.clone(), id);
                    let coord = b.push(Op::GridCoord(id));
                    let dim = match b.func.grids[id.0 as usize].unit.as_str() {
                        "Hz" => Dim::FREQ,
                        "s" => Dim::TIME,
                        _ => Dim::NONE,
                    };
                    scope.values.insert(name.node.clone(), Tv { v: coord, dim });
                }
            }
        }
        for st in &scene.stmts {
            match st {
                SceneStmt::Param(p) => {
                    if let Some((info, dim)) = self.param_decl(p) {
                        let idx = b.func.params.len() as u32;
                        b.func.params.push(info);
                        let v = b.push(Op::Param(idx));
                        scope.values.insert(p.name.node.clone(), Tv { v, dim });
                    } else {
                        scope.poisoned.insert(p.name.node.clone());
                    }
                }
                SceneStmt::Input { name, ty, default } => {
                    if let Some((ity, dim, scale, unit)) = self.type_ann(ty, &scope) {
                        let default = default.as_ref().and_then(|e| self.input_default(&b.func, &scope, e, name, ity, dim));
                        let idx = b.func.inputs.len() as u32;
                        b.func.inputs.push(ir::InputInfo {
                            name: name.node.clone(),
                            ty: ity,
                            scale,
                            unit,
                            default,
                            role: ir::InputRole::Data,
                        });
                        let v = b.push(Op::Input(idx));
                        scope.values.insert(name.node.clone(), Tv { v, dim });
                    } else {
                        scope.poisoned.insert(name.node.clone());
                    }
                }
                SceneStmt::Let(l) | SceneStmt::Output(l) => {
                    scope.lets.insert(l.name.node.clone(), LetSlot::Pending(l));
                }
                _ => {}
            }
        }
        // Elaborate every definition (so errors in unused lets are reported);
        // pruning removes what no output needs.
        let mut outputs = Vec::new();
        for st in &scene.stmts {
            match st {
                SceneStmt::Let(l) => {
                    self.lookup_let(&mut b, &mut scope, &l.name.node, l.name.span);
                }
                SceneStmt::Output(l) => {
                    if let Some(tv) = self.lookup_let(&mut b, &mut scope, &l.name.node, l.name.span) {
                        outputs.push(ir::Output { name: l.name.node.clone(), value: tv.v, unit: tv.dim.to_string(), exponent: 0 });
                    }
                }
                _ => {}
            }
        }
        b.func.outputs = outputs;
        for st in &scene.stmts {
            if let SceneStmt::Grad { output, wrt, .. } = st {
                self.grad_request(&mut b, scene, output, wrt);
            }
        }
        if self.diags.is_empty() {
            Ok(b.func)
        } else {
            Err(self.diags)
        }
    }

    /// Evaluates the scene's `knob` declarations in source order (a knob may
    /// use the knobs above it), each replaced by its override if one is given.
    pub(super) fn scene_knobs(&mut self, scene: &'a SceneDef, overrides: &'a [KnobOverride]) {
        let mut declared = Vec::new();
        for st in &scene.stmts {
            let SceneStmt::Knob(k) = st else { continue };
            let name = &k.name.node;
            declared.push(name.as_str());
            if CONSTANTS.iter().any(|c| c.name == name) {
                self.error(
                    Diagnostic::error(k.name.span, format!("knob `{name}` would hide the constant `{name}`"))
                        .with_help("give the knob another name"),
                );
                self.failed_knobs.insert(name.clone());
                continue;
            }
            if let Some(t) = &k.ty {
                self.error(
                    Diagnostic::error(t.span, "a knob takes its unit from its value")
                        .with_label("no type here")
                        .with_help(format!("write the unit on the value, e.g. `knob {name} = 0.125 Hz`")),
                );
            }
            let Some((mut x, dim)) = self.const_eval(&k.value) else {
                self.failed_knobs.insert(name.clone());
                continue;
            };
            if let Some(o) = overrides.iter().find(|o| &o.name == name) {
                match self.const_eval(&o.value) {
                    Some((y, odim)) if odim == dim => x = y,
                    Some((_, odim)) => {
                        self.error(
                            unit_mismatch(o.value.span, dim, odim, &format!("knob `{name}`"))
                                .with_secondary(k.value.span, "the scene's value"),
                        );
                        self.failed_knobs.insert(name.clone());
                        continue;
                    }
                    None => {
                        self.failed_knobs.insert(name.clone());
                        continue;
                    }
                }
            }
            if !x.is_finite() {
                self.error(
                    Diagnostic::error(k.value.span, format!("knob `{name}` is {x}"))
                        .with_label("not a finite number")
                        .with_help("a knob must be a finite number: check divisions by zero and overflow"),
                );
                self.failed_knobs.insert(name.clone());
                continue;
            }
            self.knobs.insert(name.clone(), (x, dim));
        }
        for o in overrides {
            if declared.contains(&o.name.as_str()) {
                continue;
            }
            let mut d = Diagnostic::error(o.value.span, format!("scene `{}` has no knob `{}`", scene.name.node, o.name));
            d = match did_you_mean(&o.name, declared.iter().copied()) {
                Some(s) => d.with_help(format!("did you mean `{s}`?")),
                None if declared.is_empty() => d.with_help("declare one in the scene, e.g. `knob pn_order = 7`"),
                None => d.with_help(format!("its knobs are {}", declared.join(", "))),
            };
            self.error(d);
        }
    }

    pub(super) fn grad_request(&mut self, b: &mut Builder, scene: &SceneDef, output: &Spanned<String>, wrt: &[Spanned<String>]) {
        let declared = scene.stmts.iter().any(|s| matches!(s, SceneStmt::Output(l) if l.name.node == output.node));
        let Some(oi) = b.func.outputs.iter().position(|o| o.name == output.node) else {
            if declared {
                // The output itself failed to check; that error was reported.
                return;
            }
            let outs: Vec<String> = b.func.outputs.iter().map(|o| o.name.clone()).collect();
            let mut d = Diagnostic::error(output.span, format!("`{}` is not an output of scene `{}`", output.node, scene.name.node))
                .with_label("gradients are taken of outputs");
            d = match did_you_mean(&output.node, outs.iter().map(|s| s.as_str())) {
                Some(s) => d.with_help(format!("did you mean `{s}`?")),
                None => d.with_help(format!("declare it with `output {} = ...`", output.node)),
            };
            self.error(d);
            return;
        };
        let ty = b.func.ty(b.func.outputs[oi].value);
        if ty != Ty::REAL {
            self.error(
                Diagnostic::error(
                    output.span,
                    format!("cannot differentiate `{}`: it is {}, not a real scalar", output.node, b.func.fmt_ty(ty)),
                )
                .with_help("reduce it to a real scalar first, e.g. `sum(abs2(x))`"),
            );
            return;
        }
        for w in wrt {
            if self.modules.get(&w.node).is_some_and(|m| m.learned) {
                let prefix = format!("{}.", w.node);
                let weights: Vec<usize> = (0..b.func.inputs.len())
                    .filter(|i| b.func.inputs[*i].is_weight() && b.func.inputs[*i].name.starts_with(&prefix))
                    .collect();
                if weights.is_empty() {
                    self.error(
                        Diagnostic::error(w.span, format!("learned component `{}` has no weights in this scene", w.node))
                            .with_label("not called by any output, or it declares no `weight`")
                            .with_help(format!("use it in an output, e.g. `output y = {}(x)`", w.node)),
                    );
                }
                for input in weights {
                    if !b.func.input_grads.iter().any(|g| g.output == oi && g.input == input) {
                        b.func.input_grads.push(ir::InputGrad { output: oi, input, value: None });
                    }
                }
                continue;
            }
            match b.func.params.iter().position(|p| p.name == w.node) {
                Some(pi) => {
                    if !b.func.grads.iter().any(|g| g.output == oi && g.param == pi) {
                        b.func.grads.push(ir::GradOutput { output: oi, param: pi, value: None });
                    }
                }
                None => {
                    let is_other = scene.stmts.iter().find_map(|s| match s {
                        SceneStmt::Input { name, .. } if name.node == w.node => Some("an input"),
                        SceneStmt::Let(l) if l.name.node == w.node => Some("a `let`"),
                        SceneStmt::Output(l) if l.name.node == w.node => Some("an output"),
                        SceneStmt::Grid { name, .. } if name.node == w.node => Some("a grid"),
                        _ => None,
                    });
                    let params: Vec<&str> = b.func.params.iter().map(|p| p.name.as_str()).collect();
                    let mut d = Diagnostic::error(w.span, format!("cannot take a gradient with respect to `{}`", w.node));
                    d = match is_other {
                        Some(kind) => d
                            .with_label(format!("`{}` is {kind}, not a param", w.node))
                            .with_help(format!("declare it as `param {}` to differentiate with respect to it", w.node)),
                        None => {
                            let d = d.with_label("not a param of this scene");
                            match did_you_mean(&w.node, params) {
                                Some(s) => d.with_help(format!("did you mean `{s}`?")),
                                None => d.with_help("gradients are taken with respect to `param`s"),
                            }
                        }
                    };
                    self.error(d);
                }
            }
        }
    }
}
