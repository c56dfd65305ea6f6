//! The scene reference (docs/scene-reference.md) and the TOML examples of the documentation,
//! checked against the program's own parsers (no MPI, no meshing: the parsers read text and
//! check that the files named exist):
//!
//! - every ```toml block of README.md, docs/*.md and examples/**/*.md parses, by the
//!   convention stated in docs/scene-reference.md ("How to read this reference"): a complete
//!   scene (it has `[mesh]`, `[material]` and `[time]`), a scene fragment (merged into a small
//!   base scene), a study file (first line `# study file`) or a suite file (first line
//!   `# suite file`);
//! - the key paths the reference documents are exactly those the parsers accept, and every key
//!   with a fixed set of values lists exactly those values. What the parsers accept is found by
//!   probing them: an unknown key in a table makes them list the table's keys, an unknown value
//!   of a key with a fixed set of values makes them list the values, so nothing here is a
//!   hand-written list of keys.
//!
//! The reference's machine-readable form: a table whose first header cell is `Key` documents
//! one key path per row, in backticks in the first cell (`material.E`, `body[].group`,
//! `mesh.params.<name>` for keys of the user's choice, `output.field_every.<field>` for each
//! value of `output.fields`). Its `Type` cell lists the allowed values of a key with a fixed
//! set as `"value"` spans, or a table headed `` `key.path` value `` lists them in its first
//! column; an `Obstacle` column names the obstacle types that take the key (`all`: every type).
//! Rows under a `##` heading that says "Study file" or "Suite file" are keys of those files;
//! the others are scene keys. An entry of `contact.obstacles` takes the keys documented for
//! `contact.obstacle`, a study's `[[part]]` those documented for a study (plus `part[].name`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use massfree::{scene, study, suite};
use toml::{Table, Value};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The reference this test holds to the parsers.
const REFERENCE: &str = "docs/scene-reference.md";

// =============================================================================================
// The parsers

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Format {
    Scene,
    Study,
    Suite,
}

impl Format {
    fn name(self) -> &'static str {
        match self {
            Format::Scene => "scene",
            Format::Study => "study",
            Format::Suite => "suite",
        }
    }
}

/// A scene text parsed as the program does, relative mesh paths against `base`.
fn parse_scene_in(text: &str, base: &Path) -> Result<(), String> {
    scene::parse(text, "example.toml", base).map(|_| ()).map_err(|e| e.to_string())
}

/// The first success of `f` over the folders, else the most telling error: the first that is
/// not about a missing file, or the first one.
fn in_one_of(
    text: &str,
    dirs: &[PathBuf],
    f: fn(&str, &Path) -> Result<(), String>,
) -> Result<(), String> {
    let mut errors = Vec::new();
    for d in dirs {
        match f(text, d) {
            Ok(()) => return Ok(()),
            Err(e) => errors.push(e),
        }
    }
    let missing_file = |e: &String| {
        e.contains("file not found") || e.contains("no such file") || e.contains("cannot read")
    };
    let first = errors.iter().find(|e| !missing_file(e)).or(errors.first());
    Err(first.cloned().unwrap_or_default())
}

/// Where the paths of a documented file may point from: the repository root, the shipped
/// scenes' folder (`../meshes/...`) or studies' folder (`../scenes/...`), the Markdown file's
/// own folder.
fn folders(format: Format, doc_dir: &Path) -> Vec<PathBuf> {
    let first = match format {
        Format::Scene => vec![repo(), repo().join("scenes")],
        Format::Study | Format::Suite => vec![repo().join("studies"), repo()],
    };
    first.into_iter().chain([doc_dir.to_path_buf()]).collect()
}

/// A study file's text, as if the file were in `dir` (its `scene` is relative to it).
fn parse_study_in(text: &str, dir: &Path) -> Result<(), String> {
    study::spec::parse_set(&dir.join("example.toml"), text).map(|_| ()).map_err(|e| e.to_string())
}

/// A suite file's text, as if the file were in `dir`, with and without its reduced variant.
fn parse_suite_in(text: &str, dir: &Path) -> Result<(), String> {
    for reduced in [false, true] {
        suite::spec::parse(&dir.join("example.toml"), text, reduced).map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// A probe's document, with each file where the shipped ones are (a suite with and without
/// its reduced variant).
fn parse_as(format: Format, text: &str) -> Result<(), String> {
    match format {
        Format::Scene => parse_scene_in(text, &repo()),
        Format::Study => parse_study_in(text, &repo().join("studies")),
        Format::Suite => parse_suite_in(text, &repo().join("studies")),
    }
}

// =============================================================================================
// The TOML blocks of the documentation

/// The base scene a fragment is merged into. Its mesh exists (the parser checks that).
const BASE_SCENE: &str = r#"
[mesh]
geo = "meshes/disc_quad.geo"
[material]
E = 100.0
nu = 0.3
rho = 1.0
[time]
tau = 1e-3
steps = 1000
"#;

/// `a` with `b`'s keys: tables merged key by key, anything else (values, arrays of tables)
/// taken from `b`.
fn deep_merge(a: &mut Table, b: &Table) {
    for (k, v) in b {
        match (a.get_mut(k), v) {
            (Some(Value::Table(x)), Value::Table(y)) => deep_merge(x, y),
            _ => {
                a.insert(k.clone(), v.clone());
            }
        }
    }
}

/// Whether one ```toml block of a Markdown file in `doc_dir` parses, by the convention of the
/// reference.
fn check_block(text: &str, doc_dir: &Path) -> Result<(), String> {
    let first = text.lines().next().unwrap_or("").trim().to_ascii_lowercase();
    if first.starts_with("# study file") {
        return in_one_of(text, &folders(Format::Study, doc_dir), parse_study_in)
            .map_err(|e| format!("study file: {e}"));
    }
    if first.starts_with("# suite file") {
        return in_one_of(text, &folders(Format::Suite, doc_dir), parse_suite_in)
            .map_err(|e| format!("suite file: {e}"));
    }
    let scene_dirs = folders(Format::Scene, doc_dir);
    let parse_scene = |text: &str| in_one_of(text, &scene_dirs, parse_scene_in);
    let table: Table = text.parse().map_err(|e: toml::de::Error| {
        format!("invalid TOML: {}", e.message().lines().next().unwrap_or("").trim())
    })?;
    if ["mesh", "material", "time"].iter().all(|k| table.contains_key(*k)) {
        return parse_scene(text).map_err(|e| format!("complete scene: {e}"));
    }
    // A fragment: merged into the base key by key, or with its tables replacing the base's
    // (a fragment's `[time]` with `end` replaces the base's `steps`).
    let base: Table = BASE_SCENE.parse().expect("the base scene is TOML");
    let mut merged = base.clone();
    deep_merge(&mut merged, &table);
    let mut replaced = base;
    replaced.extend(table);
    let as_text = |t: &Table| toml::to_string(t).expect("a table writes as TOML");
    match parse_scene(&as_text(&merged)) {
        Ok(()) => Ok(()),
        Err(e) => match parse_scene(&as_text(&replaced)) {
            Ok(()) => Ok(()),
            Err(_) => Err(format!("scene fragment (merged into the base scene): {e}")),
        },
    }
}

/// The fenced blocks of one language of a Markdown text: (the fence's line number, text).
fn blocks(text: &str, lang: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut current: Option<(usize, String)> = None;
    let mut other = false;
    for (i, line) in text.lines().enumerate() {
        if let Some(rest) = line.trim_start().strip_prefix("```") {
            if let Some(block) = current.take() {
                out.push(block);
            } else if other {
                other = false;
            } else if rest.trim() == lang {
                current = Some((i + 1, String::new()));
            } else {
                other = true;
            }
            continue;
        }
        if let Some((_, body)) = current.as_mut() {
            body.push_str(line);
            body.push('\n');
        }
    }
    out
}

/// Markdown files under `dir`, recursively.
fn markdown_under(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            markdown_under(&p, out);
        } else if p.extension().is_some_and(|x| x == "md") {
            out.push(p);
        }
    }
}

/// Every failing ```toml block of `files`: `file:line: kind: error`.
fn failing_blocks(files: &[PathBuf]) -> Vec<String> {
    let mut failures = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        let shown = f.strip_prefix(repo()).unwrap_or(f).display().to_string();
        for (line, block) in blocks(&text, "toml") {
            let dir = f.parent().unwrap_or(Path::new("."));
            if let Err(e) = check_block(&block, dir) {
                failures.push(format!("{shown}:{line}: {}", e.lines().next().unwrap_or("")));
            }
        }
    }
    failures
}

fn assert_blocks_parse(files: &[PathBuf]) {
    let failures = failing_blocks(files);
    assert!(
        failures.is_empty(),
        "{} ```toml block(s) do not parse with the program's parsers (convention: the top of {REFERENCE}; \
         shell commands, output and pseudo-syntax with \"...\" belong in ```sh / ```text blocks):\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn toml_blocks_of_docs_and_examples_parse() {
    let mut files = Vec::new();
    markdown_under(&repo().join("docs"), &mut files);
    markdown_under(&repo().join("examples"), &mut files);
    files.sort();
    assert!(files.iter().any(|f| f.ends_with(REFERENCE)), "{REFERENCE} is missing");
    assert_blocks_parse(&files);
}

#[test]
fn toml_blocks_of_readme_parse() {
    assert_blocks_parse(&[repo().join("README.md")]);
}

/// `file:line` of every line of `text` with a control character, or that follows a line
/// ending in `$` and starts with `u` and a math character: a TeX `\frac`, `\to` or `\nu`
/// written through an escaping string becomes a form feed, a tab or a line break.
fn control_characters(shown: &str, text: &str) -> Vec<String> {
    let lines: Vec<&str> = text.lines().collect();
    let broken_nu = |i: usize| {
        let l = lines[i].trim_start();
        i > 0
            && lines[i - 1].ends_with('$')
            && ["u$", "u ", "u_", "u="].iter().any(|p| l.starts_with(p))
    };
    (0..lines.len())
        .filter(|&i| lines[i].chars().any(|c| c.is_control()) || broken_nu(i))
        .map(|i| format!("{shown}:{}", i + 1))
        .collect()
}

/// No Markdown page (README, CHANGELOG, docs, examples) holds a control character or a
/// `\nu` broken into a line break and a `u`: a broken TeX command renders as garbage (it
/// happened twice). The check's own failures are shown on made-up pages.
#[test]
fn markdown_pages_hold_no_control_characters() {
    let bad = control_characters("page.md", "at $\\frac{a}{b}$, $\x0crac{a}{b}$,\n$\to 1$");
    assert_eq!(bad, ["page.md:1", "page.md:2"], "the check cannot fail");
    let bad = control_characters("page.md", "peak at $\nu$ = 0.4999\nu and v, $\\nu$");
    assert_eq!(bad, ["page.md:2"], "the check cannot fail");
    let mut files = vec![repo().join("README.md"), repo().join("CHANGELOG.md")];
    markdown_under(&repo().join("docs"), &mut files);
    markdown_under(&repo().join("examples"), &mut files);
    let found: Vec<String> = (files.iter())
        .flat_map(|f| {
            let text =
                std::fs::read_to_string(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            control_characters(&f.strip_prefix(repo()).unwrap_or(f).display().to_string(), &text)
        })
        .collect();
    assert!(
        found.is_empty(),
        "control characters (a TeX command lost its backslash?):\n{}",
        found.join("\n")
    );
}

#[test]
fn the_block_check_can_fail() {
    // Each kind of block, good and bad: the check is not vacuous.
    let good_fragment = "[contact]\nboundary = \"contact\"\nobstacle = { type = \"plane\", point = [0.0, 0.0], normal = [0.0, 1.0] }\n";
    assert_eq!(check_block(good_fragment, &repo()), Ok(()));
    assert_eq!(check_block("[time]\ntau = 0.5\nend = 2.0\n", &repo()), Ok(()));
    let e =
        check_block("[contact]\nboundary = \"contact\"\nobstacle = { type = \"cone\" }\n", &repo());
    assert!(e.as_ref().is_err_and(|e| e.contains("cone")), "{e:?}");
    let e = check_block("[material]\nE = 1.0\nnu = 0.5\nrho = 1.0\n", &repo());
    assert!(e.as_ref().is_err_and(|e| e.contains("material.nu")), "{e:?}");
    let complete = format!("{BASE_SCENE}[output]\nevery = 0\n");
    assert!(check_block(&complete, &repo()).is_err_and(|e| e.contains("output.every")));
    assert_eq!(check_block(BASE_SCENE, &repo()), Ok(()));
    let study = "# study file\nscene = \"../scenes/beam.toml\"\n[sweep]\nh = [0.25, 0.125]\n";
    assert_eq!(check_block(study, &repo()), Ok(()));
    let e = check_block(&study.replace("h = [", "hh = ["), &repo());
    assert!(e.as_ref().is_err_and(|e| e.contains("sweep.hh")), "{e:?}");
    let suite =
        "# suite file\n[[case]]\nname = \"a\"\ngroup = \"g\"\nscene = \"../scenes/beam.toml\"\n";
    assert_eq!(check_block(suite, &repo()), Ok(()));
    assert!(check_block(&suite.replace("group", "grupp"), &repo()).is_err());
}

// =============================================================================================
// Probing the parsers for the key paths they accept

/// A key the parsers do not know, and a value no key with a fixed set of values takes.
const KEY: &str = "zzz_key";
const VALUE: &str = "zzz_value";

/// What the parsers take at a key path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// A value (number, string, array of values).
    Leaf,
    /// A table with fixed keys.
    Table,
    /// An array of tables with fixed keys (path segment `key[]`).
    Array,
    /// A table whose keys are the user's (`key.<*>`).
    Free,
}

#[derive(Debug, Clone)]
struct Found {
    kind: Kind,
    /// The fixed set of values (a string, or each element of an array of strings).
    values: BTreeSet<String>,
    /// In a table with a type tag (an obstacle): the tag values that take this key.
    variants: BTreeSet<String>,
}

/// How a parser takes a table at a path.
enum Shape {
    /// Not a table there.
    NotTable,
    /// The parser rejects the key itself there.
    Rejected,
    /// Fixed keys, and a document in which the table is complete (its required keys set).
    Fixed { keys: Vec<String>, context: Table },
    /// Fixed keys per value of a tag key (`type`).
    Tagged { tag: String, variants: Vec<(String, Vec<String>, Table)> },
    /// Any key.
    Free,
}

/// Sets `path` in `doc` (segment `k[]`: the first table of the array `k`), creating tables
/// and arrays on the way.
fn set(doc: &mut Table, path: &[String], value: Value) {
    let (last, parents) = path.split_last().expect("a non-empty path");
    let mut at = doc;
    for seg in parents {
        at = match seg.strip_suffix("[]") {
            Some(k) => {
                let ok = matches!(at.get(k), Some(Value::Array(a)) if matches!(a.first(), Some(Value::Table(_))));
                if !ok {
                    at.insert(k.to_string(), Value::Array(vec![Value::Table(Table::new())]));
                }
                match at.get_mut(k) {
                    Some(Value::Array(a)) => match a.first_mut() {
                        Some(Value::Table(t)) => t,
                        _ => unreachable!(),
                    },
                    _ => unreachable!(),
                }
            }
            None => {
                if !matches!(at.get(seg.as_str()), Some(Value::Table(_))) {
                    at.insert(seg.clone(), Value::Table(Table::new()));
                }
                match at.get_mut(seg.as_str()) {
                    Some(Value::Table(t)) => t,
                    _ => unreachable!(),
                }
            }
        };
    }
    match last.strip_suffix("[]") {
        Some(k) => {
            at.insert(k.to_string(), Value::Array(vec![value]));
        }
        None => {
            at.insert(last.clone(), value);
        }
    }
}

/// The value at `path`, if any.
fn get<'a>(doc: &'a Table, path: &[String]) -> Option<&'a Value> {
    let (last, parents) = path.split_last()?;
    let mut at = doc;
    for seg in parents {
        at = match seg.strip_suffix("[]") {
            Some(k) => match at.get(k)? {
                Value::Array(a) => a.first()?.as_table()?,
                _ => return None,
            },
            None => at.get(seg.as_str())?.as_table()?,
        };
    }
    match last.strip_suffix("[]") {
        Some(k) => at.get(k)?.as_array()?.first(),
        None => at.get(last.as_str()),
    }
}

fn join(path: &[String], key: &str) -> Vec<String> {
    let mut p = path.to_vec();
    p.push(key.to_string());
    p
}

fn shown(path: &[String]) -> String {
    path.join(".")
}

/// The list of names in a parser's error after "allowed:", "expected one of" or "use"
/// (serde's, the scene's, the study's and the suite's forms), without the probe's own names.
fn allowed(e: &str) -> Vec<String> {
    let items: Vec<String> = if let Some(i) = e.find("(allowed: ") {
        let rest = &e[i + "(allowed: ".len()..];
        let end = rest.find(')').unwrap_or(rest.len());
        rest[..end].split(',').map(|s| s.to_string()).collect()
    } else if let Some(i) = e.find(", expected ") {
        e[i..].split('`').skip(1).step_by(2).map(|s| s.to_string()).collect()
    } else if let Some(i) = e.find(": use ") {
        e[i..].split('"').skip(1).step_by(2).map(|s| s.to_string()).collect()
    } else {
        Vec::new()
    };
    items
        .iter()
        .map(|s| s.trim().trim_matches(|c| c == '"' || c == '`').to_string())
        .filter(|s| !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'))
        .filter(|s| s != KEY && s != VALUE)
        .collect()
}

/// The values an error about the probe's value lists as allowed: the value quoted whole
/// (`"zzz_value"`, not a name inside an expression), then the list.
fn listed_values(e: &str) -> Vec<String> {
    let quoted = [format!("\"{VALUE}\""), format!("`{VALUE}`")];
    let Some(at) = quoted.iter().filter_map(|q| e.find(q.as_str())).min() else {
        return Vec::new();
    };
    if e.contains("wrong type") || e.contains("invalid type") || unknown_key(e) {
        return Vec::new();
    }
    allowed(&e[at..])
}

/// The key a parser's error says is missing (its last path segment).
fn missing(e: &str) -> Option<String> {
    let full = if let Some(i) = e.find("missing key \"") {
        let rest = &e[i + "missing key \"".len()..];
        rest[..rest.find('"')?].to_string()
    } else if let Some(i) = e.find("missing field `") {
        let rest = &e[i + "missing field `".len()..];
        rest[..rest.find('`')?].to_string()
    } else if let Some(i) = e.find(": missing") {
        e[..i].split_whitespace().last()?.to_string()
    } else {
        return None;
    };
    let last = full.rsplit('.').next()?;
    Some(last.split('[').next()?.to_string())
}

fn unknown_key(e: &str) -> bool {
    e.contains("unknown key") || e.contains("unknown field")
}

/// Values tried for a required key until the parser takes one.
fn candidates() -> Vec<Value> {
    let s = |x: &str| Value::String(x.to_string());
    vec![
        s(VALUE),
        Value::Float(0.25),
        Value::Integer(1),
        Value::Array(vec![s("0"), s("0")]),
        Value::Array(vec![Value::Float(0.0), Value::Float(1.0)]),
        Value::Boolean(false),
    ]
}

struct Probe {
    format: Format,
    found: BTreeMap<String, Found>,
    problems: Vec<String>,
}

impl Probe {
    fn parse(&self, doc: &Table) -> Result<(), String> {
        let text = toml::to_string(doc).expect("a table writes as TOML");
        parse_as(self.format, &text)
    }

    fn record(&mut self, path: &str, kind: Kind, values: BTreeSet<String>, variant: Option<&str>) {
        let f = self.found.entry(path.to_string()).or_insert_with(|| Found {
            kind,
            values: BTreeSet::new(),
            variants: BTreeSet::new(),
        });
        f.values.extend(values);
        f.variants.extend(variant.map(String::from));
    }

    /// The keys of the table at `at` in `doc` (required keys the parser only asks for before
    /// the others filled in), or a problem.
    fn fixed_keys(&mut self, doc: &Table, at: &[String]) -> Option<Vec<String>> {
        let mut d = doc.clone();
        set(&mut d, &join(at, KEY), Value::Integer(1));
        match self.parse(&d) {
            Err(e) if e.contains(KEY) && unknown_key(&e) && !allowed(&e).is_empty() => {
                Some(allowed(&e))
            }
            other => {
                self.problems.push(format!(
                    "{} {}: an unknown key there gives no list of keys: {other:?}",
                    self.format.name(),
                    shown(at)
                ));
                None
            }
        }
    }

    /// The required keys of the table at `at` set (the parser's errors name them), without
    /// the probe key: a document the parser takes as far as that table goes.
    fn complete(&mut self, doc: &mut Table, at: &[String]) {
        let mut tried = BTreeSet::new();
        while let Err(e) = self.parse(doc) {
            let Some(m) = missing(&e) else { return };
            if !tried.insert(m.clone()) {
                return;
            }
            let path = join(at, &m);
            let fits = candidates().into_iter().find(|c| {
                let mut d = doc.clone();
                set(&mut d, &path, c.clone());
                match self.parse(&d) {
                    Ok(()) => true,
                    Err(e) => {
                        missing(&e).as_deref() != Some(m.as_str())
                            && !e.contains(VALUE)
                            && !e.contains("wrong type")
                            && !e.contains("invalid type")
                            && !e.contains("is expected")
                    }
                }
            });
            match fits {
                Some(c) => set(doc, &path, c),
                None => return,
            }
        }
    }

    /// How the parser takes a table at `at` (the last segment `k[]`: an array of tables).
    fn shape(&mut self, doc: &Table, at: &[String]) -> Shape {
        let key = at.last().expect("a key").trim_end_matches("[]").to_string();
        let existing = matches!(get(doc, at), Some(Value::Table(_)));
        let mut fresh = doc.clone();
        set(&mut fresh, at, Value::Table(Table::new()));
        let mut probe = fresh.clone();
        set(&mut probe, &join(at, KEY), Value::Integer(1));
        let mut required: Vec<String> = Vec::new();
        loop {
            let e = match self.parse(&probe) {
                Ok(()) => return Shape::Free,
                Err(e) => e,
            };
            if let Some(m) = missing(&e).filter(|m| m != KEY && !required.contains(m)) {
                let path = join(at, &m);
                // A type tag: an unknown value lists the types.
                let mut d = probe.clone();
                set(&mut d, &path, Value::String(VALUE.into()));
                if let Err(e2) = self.parse(&d) {
                    let types = listed_values(&e2);
                    if !types.is_empty() {
                        let mut variants = Vec::new();
                        for t in types {
                            let mut ctx = fresh.clone();
                            set(&mut ctx, &path, Value::String(t.clone()));
                            let Some(keys) = self.fixed_keys(&ctx, at) else {
                                return Shape::NotTable;
                            };
                            self.complete(&mut ctx, at);
                            variants.push((t, keys, ctx));
                        }
                        return Shape::Tagged { tag: m, variants };
                    }
                }
                // A required key asked for before the others: fill it in.
                let fits = candidates().into_iter().find(|c| {
                    let mut d = probe.clone();
                    set(&mut d, &path, c.clone());
                    match self.parse(&d) {
                        Ok(()) => true,
                        Err(e3) => e3.contains(KEY) || missing(&e3).is_some_and(|m3| m3 != m),
                    }
                });
                let Some(c) = fits else {
                    self.problems.push(format!(
                        "{} {}: no value found for the required key {m}",
                        self.format.name(),
                        shown(at)
                    ));
                    return Shape::NotTable;
                };
                set(&mut probe, &path, c.clone());
                set(&mut fresh, &path, c);
                required.push(m);
                continue;
            }
            if e.contains(KEY) && unknown_key(&e) && !allowed(&e).is_empty() {
                let mut keys = allowed(&e);
                keys.extend(
                    required.iter().filter(|r| !keys.contains(r)).cloned().collect::<Vec<_>>(),
                );
                let mut context = if existing { doc.clone() } else { fresh };
                self.complete(&mut context, at);
                return Shape::Fixed { keys, context };
            }
            if e.contains(&format!("{key}.{KEY}")) {
                return Shape::Free;
            }
            if unknown_key(&e) && e.contains(&key) && !e.contains(KEY) {
                return Shape::Rejected;
            }
            return Shape::NotTable;
        }
    }

    /// The fixed values of the key at `path` (a string, or an array of strings; a table may
    /// take a string too), if any.
    fn values(&mut self, doc: &Table, path: &[String], table: bool) -> BTreeSet<String> {
        let one = Value::String(VALUE.into());
        // A table is not probed with an array: serde reads a struct from one, field by field.
        let tries = if table { vec![one] } else { vec![one.clone(), Value::Array(vec![one])] };
        for v in tries {
            let mut d = doc.clone();
            set(&mut d, path, v);
            if let Err(e) = self.parse(&d) {
                let list = listed_values(&e);
                if !list.is_empty() {
                    return list.into_iter().collect();
                }
            }
        }
        BTreeSet::new()
    }

    /// Records the keys of the table at `at` (in `doc`, complete there) and what lies below.
    fn explore(&mut self, doc: &Table, at: &[String], keys: &[String], variant: Option<&str>) {
        for k in keys {
            let child = join(at, k);
            let name = shown(&child);
            match self.shape(doc, &child) {
                Shape::Rejected => {}
                Shape::Fixed { keys, context } => {
                    // A table that also takes a string of a fixed set (the study's reference).
                    let values = self.values(doc, &child, true);
                    self.record(&name, Kind::Table, values, variant);
                    self.explore(&context, &child, &keys, None);
                }
                Shape::Tagged { tag, variants } => {
                    self.record(&name, Kind::Table, BTreeSet::new(), variant);
                    self.tagged(&child, &tag, variants);
                }
                Shape::Free => {
                    self.record(&name, Kind::Table, BTreeSet::new(), variant);
                    self.record(&format!("{name}.<*>"), Kind::Free, BTreeSet::new(), None);
                }
                Shape::NotTable => {
                    let array = join(at, &format!("{k}[]"));
                    let array_name = shown(&array);
                    match self.shape(doc, &array) {
                        Shape::Fixed { keys, context } => {
                            self.record(&array_name, Kind::Array, BTreeSet::new(), variant);
                            self.explore(&context, &array, &keys, None);
                        }
                        Shape::Tagged { tag, variants } => {
                            self.record(&array_name, Kind::Array, BTreeSet::new(), variant);
                            self.tagged(&array, &tag, variants);
                        }
                        Shape::Free => {
                            self.record(&array_name, Kind::Array, BTreeSet::new(), variant);
                            self.record(
                                &format!("{array_name}.<*>"),
                                Kind::Free,
                                BTreeSet::new(),
                                None,
                            );
                        }
                        Shape::NotTable | Shape::Rejected => {
                            let values = self.values(doc, &child, false);
                            self.record(&name, Kind::Leaf, values, variant);
                        }
                    }
                }
            }
        }
    }

    fn tagged(&mut self, at: &[String], tag: &str, variants: Vec<(String, Vec<String>, Table)>) {
        let types: BTreeSet<String> = variants.iter().map(|(t, _, _)| t.clone()).collect();
        self.record(&shown(&join(at, tag)), Kind::Leaf, types, None);
        for (t, keys, ctx) in variants {
            self.explore(&ctx, at, &keys, Some(&t));
        }
    }

    /// Every key path the parser accepts, starting from each base document (valid files).
    fn run(format: Format, bases: &[&str]) -> Probe {
        let mut p = Probe { format, found: BTreeMap::new(), problems: Vec::new() };
        for base in bases {
            let doc: Table = base.parse().expect("a base document is TOML");
            if let Err(e) = p.parse(&doc) {
                panic!("the {} probe's base document does not parse: {e}\n{base}", format.name());
            }
            if let Some(keys) = p.fixed_keys(&doc, &[]) {
                p.explore(&doc, &[], &keys, None);
            }
        }
        assert!(
            p.problems.is_empty(),
            "probing the {} parser:\n{}",
            format.name(),
            p.problems.join("\n")
        );
        p
    }
}

const STUDY_BASE: &str = r#"
scene = "../scenes/beam.toml"
[sweep]
h = [0.25, 0.125]
"#;

/// A study file with parts: its top level takes other keys.
const STUDY_PARTS_BASE: &str = r#"
[[part]]
name = "a"
scene = "../scenes/beam.toml"
[part.sweep]
h = [0.25, 0.125]
"#;

const SUITE_BASE: &str = r#"
[[case]]
name = "a"
group = "g"
scene = "../scenes/beam.toml"
"#;

fn probe(format: Format) -> Probe {
    match format {
        Format::Scene => Probe::run(format, &[BASE_SCENE]),
        Format::Study => Probe::run(format, &[STUDY_BASE, STUDY_PARTS_BASE]),
        Format::Suite => Probe::run(format, &[SUITE_BASE]),
    }
}

// =============================================================================================
// The key tables of the reference

/// One row of a table headed `Key`.
#[derive(Debug, Clone)]
struct Row {
    line: usize,
    /// The key path as written, placeholders `<...>` kept.
    path: String,
    /// The quoted values (`"name"` in backticks) of its `Type` cell: the allowed values.
    values: BTreeSet<String>,
    /// Its `Obstacle` cell, if the table has that column.
    obstacle: Option<String>,
}

/// What the reference documents, per file format: its key rows, and the values listed in
/// value tables (a table whose first header cell names a key path in backticks and says
/// "value").
#[derive(Debug, Default)]
struct Reference {
    rows: BTreeMap<Format, Vec<Row>>,
    value_tables: BTreeMap<(Format, String), BTreeSet<String>>,
}

fn cells(line: &str) -> Vec<String> {
    let t = line.trim();
    let t = t.strip_prefix('|').unwrap_or(t);
    let t = t.strip_suffix('|').unwrap_or(t);
    t.split('|').map(|c| c.trim().to_string()).collect()
}

/// The backticked spans of a cell.
fn code_spans(cell: &str) -> Vec<String> {
    cell.split('`').skip(1).step_by(2).map(str::to_string).collect()
}

/// `"name"` spans of a cell: the values it lists.
fn quoted_values(cell: &str) -> BTreeSet<String> {
    code_spans(cell)
        .iter()
        .filter_map(|s| s.strip_prefix('"').and_then(|s| s.strip_suffix('"')).map(str::to_string))
        .collect()
}

fn read_reference(text: &str) -> Reference {
    let mut r = Reference::default();
    let mut format = Format::Scene;
    let lines: Vec<&str> = text.lines().collect();
    let mut i = 0;
    let mut fenced = false;
    while i < lines.len() {
        let line = lines[i];
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        }
        if fenced {
            i += 1;
            continue;
        }
        if let Some(h) = line.strip_prefix("## ") {
            let h = h.to_ascii_lowercase();
            format = if h.contains("study file") {
                Format::Study
            } else if h.contains("suite file") {
                Format::Suite
            } else {
                Format::Scene
            };
        }
        let is_table = line.trim_start().starts_with('|')
            && lines.get(i + 1).is_some_and(|l| {
                l.trim_start().starts_with("|--")
                    || l.trim_start().starts_with("| --")
                    || l.trim_start().starts_with("|:-")
            });
        if !is_table {
            i += 1;
            continue;
        }
        let header = cells(line);
        let col = |name: &str| header.iter().position(|h| h.eq_ignore_ascii_case(name));
        let (type_col, obstacle_col) = (col("Type"), col("Obstacle"));
        let value_of = (header[0].to_ascii_lowercase().contains("value"))
            .then(|| code_spans(&header[0]).into_iter().next())
            .flatten();
        let keyed = header[0] == "Key";
        i += 2;
        while i < lines.len() && lines[i].trim_start().starts_with('|') {
            let c = cells(lines[i]);
            let spans = code_spans(&c[0]);
            if keyed {
                assert!(
                    spans.len() == 1 && c[0] == format!("`{}`", spans[0]),
                    "{REFERENCE}:{}: the first cell of a Key table must be one key path in backticks, found {:?}",
                    i + 1,
                    c[0]
                );
                r.rows.entry(format).or_default().push(Row {
                    line: i + 1,
                    path: spans[0].clone(),
                    values: type_col
                        .and_then(|k| c.get(k))
                        .map(|s| quoted_values(s))
                        .unwrap_or_default(),
                    obstacle: obstacle_col.and_then(|k| c.get(k)).cloned(),
                });
            } else if let Some(key) = &value_of {
                if let Some(v) = spans.first() {
                    let v = v.trim_matches('"').to_string();
                    r.value_tables.entry((format, key.clone())).or_default().insert(v);
                }
            }
            i += 1;
        }
    }
    r
}

/// Documented paths stand for accepted ones: `<field>` for each value of `output.fields`,
/// any other `<name>` for a key of the user's choice.
fn expand(path: &str, probe: &Probe) -> Vec<String> {
    let mut out = vec![String::new()];
    for (n, seg) in path.split('.').enumerate() {
        let choices: Vec<String> = if seg == "<field>" {
            probe
                .found
                .get("output.fields")
                .map(|f| f.values.iter().cloned().collect())
                .unwrap_or_default()
        } else if seg.starts_with('<') && seg.ends_with('>') {
            vec!["<*>".to_string()]
        } else {
            vec![seg.to_string()]
        };
        out = out
            .iter()
            .flat_map(|p| {
                choices.iter().map(move |c| if n == 0 { c.clone() } else { format!("{p}.{c}") })
            })
            .collect();
    }
    out
}

/// Documentation aliases: the keys of each obstacle of `contact.obstacles` are those of
/// `contact.obstacle`, a study part's are a study's (the reference documents them once).
fn aliases(format: Format) -> &'static [(&'static str, &'static str)] {
    match format {
        Format::Scene => &[("contact.obstacles[].", "contact.obstacle.")],
        Format::Study => &[("part[].", "")],
        Format::Suite => &[],
    }
}

/// The documented form of an accepted path: itself, or its alias.
fn documented_as<'a>(
    path: &str,
    format: Format,
    documented: &'a BTreeMap<String, Vec<&Row>>,
) -> Option<&'a Vec<&'a Row>> {
    if let Some(rows) = documented.get(path) {
        return Some(rows);
    }
    for (from, to) in aliases(format) {
        if let Some(rest) = path.strip_prefix(from) {
            if let Some(rows) = documented.get(&format!("{to}{rest}")) {
                return Some(rows);
            }
        }
    }
    None
}

/// Every disagreement between the reference's key tables for `format` and its parser.
fn disagreements(format: Format, reference: &Reference, probe: &Probe) -> Vec<String> {
    let mut out = Vec::new();
    let rows = reference.rows.get(&format).cloned().unwrap_or_default();
    // Documented path -> its rows (the expanded forms).
    let mut documented: BTreeMap<String, Vec<&Row>> = BTreeMap::new();
    for row in &rows {
        let expanded = expand(&row.path, probe);
        let mut accepted_any = false;
        for p in &expanded {
            documented.entry(p.clone()).or_default().push(row);
            // `contact.pairs` stands for the array `contact.pairs[]`.
            accepted_any |=
                probe.found.contains_key(p) || probe.found.contains_key(&format!("{p}[]"));
        }
        if !accepted_any || expanded.is_empty() {
            out.push(format!(
                "{REFERENCE}:{}: `{}` ({} file) is not a key the parser accepts",
                row.line,
                row.path,
                format.name()
            ));
        }
    }
    for (path, f) in &probe.found {
        let doc = documented_as(path, format, &documented);
        if doc.is_none() && matches!(f.kind, Kind::Leaf | Kind::Free) {
            out.push(format!(
                "{REFERENCE}: the {} parser accepts `{path}`, which no Key table row documents",
                format.name()
            ));
            continue;
        }
        let Some(doc) = doc else { continue };
        // The fixed values: the Type cells of its rows and its value table, exactly.
        let mut listed: BTreeSet<String> =
            doc.iter().flat_map(|r| r.values.iter().cloned()).collect();
        for r in doc {
            if let Some(v) = reference.value_tables.get(&(format, r.path.clone())) {
                listed.extend(v.iter().cloned());
            }
        }
        if listed != f.values {
            let line = doc.first().map_or(0, |r| r.line);
            out.push(format!(
                "{REFERENCE}:{line}: `{path}` lists the values {listed:?} but the {} parser takes {:?}{}",
                format.name(),
                f.values,
                if f.values.is_empty() { " (any: list none as `\"...\"` in its Type cell)" } else { "" }
            ));
        }
        // The obstacle types that take it.
        if !f.variants.is_empty() {
            for r in doc {
                let cell = r.obstacle.clone().unwrap_or_default();
                let parent = path.rsplit_once('.').map_or("", |(p, _)| p);
                let all: BTreeSet<String> = probe
                    .found
                    .iter()
                    .filter(|(p, _)| p.rsplit_once('.').is_some_and(|(q, _)| q == parent))
                    .flat_map(|(_, g)| g.variants.iter().cloned())
                    .collect();
                let said: BTreeSet<String> = if cell.trim() == "all" {
                    all
                } else {
                    cell.split([',', ' '])
                        .map(|w| w.trim().trim_matches('`').trim_matches('"').to_string())
                        .filter(|w| !w.is_empty() && *w != "and")
                        .collect()
                };
                if said != f.variants {
                    out.push(format!(
                        "{REFERENCE}:{}: `{path}`: its Obstacle cell says {said:?} but the parser takes it for {:?}",
                        r.line, f.variants
                    ));
                }
            }
        }
    }
    out
}

fn check_reference(format: Format) {
    let text = std::fs::read_to_string(repo().join(REFERENCE)).expect("the reference exists");
    let reference = read_reference(&text);
    let probe = probe(format);
    let problems = disagreements(format, &reference, &probe);
    assert!(
        problems.is_empty(),
        "{REFERENCE} and the {} parser disagree ({} accepted key paths found by probing):\n{}",
        format.name(),
        probe.found.len(),
        problems.join("\n")
    );
}

#[test]
fn the_reference_documents_exactly_the_scene_keys() {
    check_reference(Format::Scene);
}

#[test]
fn the_reference_documents_exactly_the_study_keys() {
    check_reference(Format::Study);
}

#[test]
fn the_reference_documents_exactly_the_suite_keys() {
    check_reference(Format::Suite);
}

#[test]
fn the_probe_finds_what_the_parsers_take() {
    // The probe is not vacuous: a few keys of each kind, as the parsers define them.
    let scene = probe(Format::Scene);
    let kind = |p: &Probe, path: &str| p.found.get(path).map(|f| f.kind);
    assert_eq!(kind(&scene, "material.E"), Some(Kind::Leaf));
    assert_eq!(kind(&scene, "body[]"), Some(Kind::Array));
    assert_eq!(kind(&scene, "mesh.params.<*>"), Some(Kind::Free));
    assert_eq!(kind(&scene, "output.field_every"), Some(Kind::Table));
    let radius = &scene.found["contact.obstacle.radius"];
    assert_eq!(radius.variants, ["cylinder", "sphere"].map(String::from).into());
    assert!(scene.found["contact.obstacle.type"].values.contains("plane"));
    assert!(scene.found["mass.kind"].values.contains("modified1"));
    assert!(scene.found["material.model"].values.contains("neo_hookean"));
    assert!(scene.found["output.fields"].values.contains("von_mises"));
    assert!(scene.found["dirichlet[].components"].values.contains("z"));
    let study = probe(Format::Study);
    assert_eq!(kind(&study, "sweep.skip[].tau"), Some(Kind::Leaf));
    assert_eq!(kind(&study, "part[].name"), Some(Kind::Leaf));
    assert_eq!(kind(&study, "part[].output"), None, "a part has no output");
    assert!(study.found["sweep.mass"].values.contains("lumped"));
    let suite = probe(Format::Suite);
    assert_eq!(kind(&suite, "case[].set.<*>"), Some(Kind::Free));
    assert_eq!(kind(&suite, "case[].reduced.skip"), Some(Kind::Leaf));
    assert!(suite.found["case[].mass"].values.contains("modified0"));
}

#[test]
fn the_reference_check_can_fail() {
    // A reference missing a row, with a row the parser does not take, and with a wrong list
    // of values: each is reported.
    let probe = probe(Format::Scene);
    let text = "## Scene\n\n| Key | Type |\n|---|---|\n| `time.tau` | number |\n| `time.tick` | number |\n| `mass.kind` | `\"consistent\"` |\n";
    let problems = disagreements(Format::Scene, &read_reference(text), &probe);
    let has = |s: &str| problems.iter().any(|p| p.contains(s));
    assert!(has("`time.tick`"), "{problems:?}");
    assert!(has("accepts `time.steps`"), "{problems:?}");
    assert!(has("`mass.kind` lists the values"), "{problems:?}");
    assert!(!has("`time.tau`"), "{problems:?}");
}

/// What the probes find, printed for a maintainer
/// (`cargo nextest run --release --test docs_reference print --no-capture`); each file format
/// has keys of its own to find.
#[test]
fn print_the_accepted_key_paths() {
    for f in [Format::Scene, Format::Study, Format::Suite] {
        let p = probe(f);
        assert!(p.found.len() >= 10, "{}: the probe found only {} keys", f.name(), p.found.len());
        for (k, v) in &p.found {
            println!("{} {k} {:?} {:?} {:?}", f.name(), v.kind, v.values, v.variants);
        }
    }
}

/// Every shipped study and suite file (studies/*.toml) parses, with its scenes: a suite file
/// has `[[case]]` tables, a study file does not.
#[test]
fn every_shipped_study_and_suite_file_parses() {
    let mut n = 0;
    for entry in std::fs::read_dir(repo().join("studies")).unwrap().flatten() {
        let path = entry.path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let dir = path.parent().unwrap();
        let parsed = if text.contains("[[case]]") {
            parse_suite_in(&text, dir)
        } else {
            parse_study_in(&text, dir)
        };
        assert!(parsed.is_ok(), "{}: {}", path.display(), parsed.unwrap_err());
        n += 1;
    }
    assert!(n >= 2, "no study files found");
}
