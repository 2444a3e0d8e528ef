//! The REPL's session: what the user has defined, the program text built
//! from it for each entry, and where every byte of that text was typed, so
//! that compile errors point at what the user wrote (`<input>:1:9`), never
//! at the generated program.

use gwml::compiler::driver::CompileError;
use gwml::compiler::front::source::{FileId, Span};
use gwml::compiler::ir::Precision;
use gwml::compiler::Program;

/// Name of the implicit scene entries are evaluated in.
pub const SCENE: &str = "__repl";
/// Name of the output an evaluated expression becomes.
pub const VALUE: &str = "__value";
/// Display name of the entry being handled, in diagnostics.
pub const INPUT: &str = "<input>";

/// What the user has defined.
#[derive(Clone, Default)]
pub struct Session {
    pub uses: Vec<String>,
    /// `(name, source)` of modules.
    pub modules: Vec<(String, String)>,
    /// `(name, source)` of scene statements: grid, param, input, let.
    pub stmts: Vec<(String, String)>,
    /// Loaded files.
    pub loaded: Vec<Loaded>,
    pub precision: Option<Precision>,
}

/// A file brought in by `:load`.
#[derive(Clone)]
pub struct Loaded {
    pub path: String,
    pub text: String,
    /// The text with its scenes blanked byte for byte (lines kept, so
    /// diagnostics keep the file's positions): what entries need, since an
    /// expression can call a loaded module but not a scene, and checking
    /// the scenes again for every entry is most of its time.
    modules: String,
}

impl Loaded {
    pub fn new(path: &str, text: String, program: &Program) -> Loaded {
        let mut bytes = text.clone().into_bytes();
        for item in &program.ast.items {
            if let gwml::compiler::front::syntax::ast::Item::Scene(scene) = item {
                for b in &mut bytes[scene.span.start..scene.span.end] {
                    if *b != b'\n' {
                        *b = b' ';
                    }
                }
            }
        }
        // Whole characters were blanked (a scene's span starts and ends on
        // character boundaries), so the bytes stay UTF-8.
        let modules = String::from_utf8(bytes).unwrap_or_else(|_| text.clone());
        Loaded { path: path.to_string(), text, modules }
    }
}

/// A new definition; its text is the entry typed.
pub enum Def {
    Use(String),
    Module(String, String),
    Stmt(String, String),
}

/// A piece of the scene body an entry adds: text the REPL writes, or a
/// part of what the user typed.
#[derive(Clone)]
pub enum Part<'a> {
    Glue(String),
    Typed(&'a str),
}

/// The program text for one entry, with the origin of each typed piece.
pub struct Generated {
    pub text: String,
    /// `(display name, text)` of everything typed that the program holds.
    origins: Vec<(String, String)>,
    pieces: Vec<Piece>,
    /// The origin of the entry being handled, if it is in the program.
    entry: Option<usize>,
}

/// `len` bytes at `at` in the program are the bytes at `offset` of origin `origin`.
struct Piece {
    at: usize,
    len: usize,
    origin: usize,
    offset: usize,
}

impl Generated {
    fn new() -> Generated {
        Generated { text: String::new(), origins: Vec::new(), pieces: Vec::new(), entry: None }
    }

    fn glue(&mut self, s: &str) {
        self.text += s;
    }

    /// Appends `text`, typed earlier, as an origin named `name`.
    fn typed(&mut self, name: String, text: &str) {
        self.origins.push((name, text.to_string()));
        self.piece(self.origins.len() - 1, text, 0);
    }

    fn piece(&mut self, origin: usize, s: &str, offset: usize) {
        self.pieces.push(Piece { at: self.text.len(), len: s.len(), origin, offset });
        self.text += s;
    }

    /// The entry's text as typed.
    fn entry(&mut self, typed: &str, s: &str) {
        let origin = *self.entry.get_or_insert_with(|| {
            self.origins.push((INPUT.to_string(), typed.to_string()));
            self.origins.len() - 1
        });
        // A definition's text is a copy of the entry.
        match offset_in(typed, s).or((s == typed).then_some(0)) {
            Some(offset) => self.piece(origin, s, offset),
            None => self.text += s,
        }
    }

    /// One line per definition of `list`, with `new` (the entry, as
    /// `(name, text)`) in place of the one it redefines or after the rest.
    fn definitions(&mut self, list: &[(String, String)], indent: &str, new: Option<(&str, &str)>, typed: &str) {
        for (name, text) in list {
            self.glue(indent);
            match new {
                Some((n, s)) if n == name => self.entry(typed, s),
                _ => self.typed(format!("<session {name}>"), text),
            }
            self.glue("\n");
        }
        if let Some((n, s)) = new {
            if !list.iter().any(|(m, _)| m == n) {
                self.glue(indent);
                self.entry(typed, s);
                self.glue("\n");
            }
        }
    }

    /// `err` with every span in the generated program (`file`) moved to
    /// where it was typed, and the generated names put in words.
    pub fn remap(&self, mut err: CompileError) -> CompileError {
        let Some(file) = err.sources.find("<repl>") else { return err };
        let ids: Vec<FileId> = self.origins.iter().map(|(name, text)| err.sources.add(name.clone(), text.clone())).collect();
        let map = |span: Span| -> Span {
            if span.file != file {
                return span;
            }
            let inside = self.pieces.iter().find(|p| p.at <= span.start && span.start <= p.at + p.len);
            match (inside, self.entry) {
                (Some(p), _) => {
                    let end = span.end.clamp(span.start, p.at + p.len);
                    Span::new(ids[p.origin], p.offset + span.start - p.at..p.offset + end - p.at)
                }
                // Text the REPL wrote around the entry: the whole entry.
                (None, Some(e)) => Span::new(ids[e], 0..self.origins[e].1.len()),
                (None, None) => span,
            }
        };
        let earlier = |span: Span| ids.iter().zip(&self.origins).find(|(id, (name, _))| **id == span.file && name.starts_with("<session "));
        for d in &mut err.diagnostics {
            d.span = map(d.span);
            if let (Some((_, (name, _))), Some(_)) = (earlier(d.span), self.entry) {
                d.notes.push(format!("{name} was defined earlier; this entry makes it fail, so the entry is not kept"));
            }
            for (s, label) in &mut d.secondary {
                *s = map(*s);
                *label = in_words(label);
            }
            d.message = in_words(&d.message);
            d.label = in_words(&d.label);
            d.help = d.help.as_deref().map(in_words);
            d.notes = d.notes.iter().map(|n| in_words(n)).collect();
        }
        err
    }
}

/// The generated names in words.
fn in_words(text: &str) -> String {
    text.replace(&format!("output `{VALUE}`"), "the entry")
        .replace(&format!("`{VALUE}`"), "the entry")
        .replace(&format!("scene `{SCENE}`"), "the session")
        .replace(&format!("`{SCENE}`"), "the session")
}

/// Where `part` starts inside `whole`, if it is a slice of it.
fn offset_in(whole: &str, part: &str) -> Option<usize> {
    let offset = (part.as_ptr() as usize).checked_sub(whole.as_ptr() as usize)?;
    (offset + part.len() <= whole.len()).then_some(offset)
}

impl Session {
    /// The session as one program, with `new` defined (typed as `typed`)
    /// and `extra` in its scene, without the loaded files' scenes (as
    /// entries are evaluated).
    pub fn source(&self, new: Option<&Def>, typed: &str, extra: &[Part]) -> Generated {
        self.source_with(new, typed, extra, false)
    }

    /// The whole session as one program, loaded scenes included.
    pub fn full_source(&self) -> Generated {
        self.source_with(None, "", &[], true)
    }

    fn source_with(&self, new: Option<&Def>, typed: &str, extra: &[Part], scenes: bool) -> Generated {
        let mut g = Generated::new();
        for (i, u) in self.uses.iter().enumerate() {
            g.typed(format!("<session use {}>", i + 1), u);
            g.glue("\n");
        }
        if let Some(Def::Use(u)) = new {
            if !self.uses.contains(u) {
                g.entry(typed, u);
                g.glue("\n");
            }
        }
        for l in &self.loaded {
            let origin = g.origins.len();
            g.origins.push((l.path.clone(), l.text.clone()));
            g.piece(origin, if scenes { &l.text } else { &l.modules }, 0);
            g.glue("\n");
        }
        let (new_module, new_stmt) = match new {
            Some(Def::Module(n, s)) => (Some((n.as_str(), s.as_str())), None),
            Some(Def::Stmt(n, s)) => (None, Some((n.as_str(), s.as_str()))),
            _ => (None, None),
        };
        g.definitions(&self.modules, "", new_module, typed);
        g.glue(&format!("scene {SCENE} {{\n"));
        g.definitions(&self.stmts, "    ", new_stmt, typed);
        for part in extra {
            match part {
                Part::Glue(s) => g.glue(s),
                Part::Typed(s) => g.entry(typed, s),
            }
        }
        g.glue("\n}\n");
        g
    }

    pub fn commit(&mut self, d: Def) {
        match d {
            Def::Use(u) => {
                if !self.uses.contains(&u) {
                    self.uses.push(u)
                }
            }
            Def::Module(n, s) => replace(&mut self.modules, &n, &s),
            Def::Stmt(n, s) => replace(&mut self.stmts, &n, &s),
        }
    }

    /// The session without definition `name`, if it has one.
    pub fn without(&self, name: &str) -> Option<Session> {
        let mut s = self.clone();
        let before = s.modules.len() + s.stmts.len();
        s.modules.retain(|(n, _)| n != name);
        s.stmts.retain(|(n, _)| n != name);
        (s.modules.len() + s.stmts.len() < before).then_some(s)
    }

    pub fn names(&self) -> Vec<String> {
        self.modules.iter().chain(&self.stmts).map(|(n, _)| n.clone()).collect()
    }
}

fn replace(list: &mut Vec<(String, String)>, name: &str, src: &str) {
    match list.iter_mut().find(|(n, _)| n == name) {
        Some(slot) => slot.1 = src.to_string(),
        None => list.push((name.to_string(), src.to_string())),
    }
}
