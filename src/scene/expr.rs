//! A small, fast math-expression compiler for loads, initial conditions and exact solutions.
//!
//! Users write scalar fields as strings in `x`, `y`, `z` (the point) and `t` (the time), e.g.
//! `"0.02*x*(10-x)*y^2*sin(2*pi*t)"`. [`Expr::parse`] tokenizes, parses (recursive descent),
//! folds constant subexpressions and compiles to a flat postfix (RPN) program with a few fused
//! instructions (`x*c`, `c-x`, `x^2`, ...). [`Expr::eval`] runs it on a fixed-size stack array:
//! no allocation, no recursion, one `match` per instruction.
//!
//! Grammar (lowest to highest precedence):
//!
//! ```text
//! expr    := term (('+' | '-') term)*
//! term    := unary (('*' | '/') unary)*
//! unary   := ('-' | '+') unary | power
//! power   := primary ('^' unary)?          right-associative; -x^2 = -(x^2), 2^-1 = 0.5
//! primary := number | x | y | z | t | pi | e | name '(' expr (',' expr)* ')' | '(' expr ')'
//! ```
//!
//! Functions: `sin cos tan exp log sqrt abs sinh cosh tanh asin acos atan` (one argument),
//! `atan2(a, b)`, `min(a, b)`, `max(a, b)`, `pow(a, b)` (two arguments). `log` is the natural
//! logarithm.

use std::fmt;

/// Deepest evaluation stack a compiled expression may need.
const STACK: usize = 32;
/// Deepest parenthesis / unary nesting the parser accepts (guards the recursion).
const MAX_NESTING: usize = 200;

const VARIABLES: &str = "x, y, z, t (and the constants pi, e)";
const FUNCTIONS: &str =
    "sin, cos, tan, exp, log, sqrt, abs, sinh, cosh, tanh, asin, acos, atan, atan2, min, max, pow";

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Un {
    Neg,
    Sin,
    Cos,
    Tan,
    Exp,
    Log,
    Sqrt,
    Abs,
    Sinh,
    Cosh,
    Tanh,
    Asin,
    Acos,
    Atan,
}

/// The one-argument functions by name (the parser reads them, [`Node`]'s `Display` writes them).
const UNARY_FUNCTIONS: [(&str, Un); 13] = [
    ("sin", Un::Sin),
    ("cos", Un::Cos),
    ("tan", Un::Tan),
    ("exp", Un::Exp),
    ("log", Un::Log),
    ("sqrt", Un::Sqrt),
    ("abs", Un::Abs),
    ("sinh", Un::Sinh),
    ("cosh", Un::Cosh),
    ("tanh", Un::Tanh),
    ("asin", Un::Asin),
    ("acos", Un::Acos),
    ("atan", Un::Atan),
];

/// The two-argument functions by name.
const BINARY_FUNCTIONS: [(&str, Bin); 4] =
    [("atan2", Bin::Atan2), ("min", Bin::Min), ("max", Bin::Max), ("pow", Bin::Pow)];

/// The entry of `table` called `name`.
fn by_name<T: Copy>(table: &[(&str, T)], name: &str) -> Option<T> {
    table.iter().find(|(n, _)| *n == name).map(|&(_, f)| f)
}

/// The name of `f` in `table` ("" if absent: never for the functions the parser builds).
fn name_of<T: Copy + PartialEq>(table: &[(&'static str, T)], f: T) -> &'static str {
    table.iter().find(|(_, g)| *g == f).map_or("", |&(n, _)| n)
}

impl Un {
    fn from_name(name: &str) -> Option<Un> {
        by_name(&UNARY_FUNCTIONS, name)
    }

    #[inline(always)]
    fn apply(self, a: f64) -> f64 {
        match self {
            Un::Neg => -a,
            Un::Sin => a.sin(),
            Un::Cos => a.cos(),
            Un::Tan => a.tan(),
            Un::Exp => a.exp(),
            Un::Log => a.ln(),
            Un::Sqrt => a.sqrt(),
            Un::Abs => a.abs(),
            Un::Sinh => a.sinh(),
            Un::Cosh => a.cosh(),
            Un::Tanh => a.tanh(),
            Un::Asin => a.asin(),
            Un::Acos => a.acos(),
            Un::Atan => a.atan(),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Bin {
    Add,
    Sub,
    Mul,
    Div,
    Pow,
    Atan2,
    Min,
    Max,
}

impl Bin {
    fn from_name(name: &str) -> Option<Bin> {
        by_name(&BINARY_FUNCTIONS, name)
    }

    #[inline(always)]
    fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            Bin::Add => a + b,
            Bin::Sub => a - b,
            Bin::Mul => a * b,
            Bin::Div => a / b,
            Bin::Pow => a.powf(b),
            Bin::Atan2 => a.atan2(b),
            Bin::Min => a.min(b),
            Bin::Max => a.max(b),
        }
    }
}

/// Parse tree: what [`Expr::parse`] compiles, and what [`super::separate`] splits.
/// `Var` indices are 0..3 = x, y, z, t.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Node {
    Num(f64),
    Var(u8),
    Un(Un, Box<Node>),
    Bin(Bin, Box<Node>, Box<Node>),
}

impl Node {
    /// Whether a variable whose index satisfies `pred` occurs.
    fn uses_var(&self, pred: &impl Fn(u8) -> bool) -> bool {
        match self {
            Node::Num(_) => false,
            Node::Var(i) => pred(*i),
            Node::Un(_, a) => a.uses_var(pred),
            Node::Bin(_, a, b) => a.uses_var(pred) || b.uses_var(pred),
        }
    }

    /// Whether `t` occurs (as [`Expr::depends_on_t`]).
    pub(super) fn depends_on_t(&self) -> bool {
        self.uses_var(&|i| i == 3)
    }

    /// Whether any of `x`, `y`, `z` occurs (as [`Expr::depends_on_x`]).
    pub(super) fn depends_on_x(&self) -> bool {
        self.uses_var(&|i| i < 3)
    }

    /// How tightly the written form binds, as in the grammar: 1 sum, 2 product, 3 sign,
    /// 4 power, 5 primary (a negative number is written with its sign).
    fn binding(&self) -> u8 {
        match self {
            Node::Bin(Bin::Add | Bin::Sub, ..) => 1,
            Node::Bin(Bin::Mul | Bin::Div, ..) => 2,
            Node::Un(Un::Neg, _) => 3,
            Node::Num(v) if v.is_finite() && v.is_sign_negative() => 3,
            Node::Bin(Bin::Pow, ..) => 4,
            _ => 5,
        }
    }
}

/// Text that [`parse_tree`] reads back into the same tree (numbers to the bit): operands are
/// parenthesized exactly where the grammar would otherwise group them differently, so
/// `a - (b - c)` and `(a*b)*c` vs `a*(b*c)` keep their shape and thus their rounding.
impl fmt::Display for Node {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let operand = |f: &mut fmt::Formatter<'_>, n: &Node, parens: bool| {
            if parens {
                write!(f, "({n})")
            } else {
                write!(f, "{n}")
            }
        };
        match self {
            // Both forms are the shortest digits that parse back to the same f64; `{}` never
            // uses an exponent (1e-300 would take 300 digits), `{:?}` writes 2 as "2.0".
            Node::Num(v) if v.is_finite() => {
                let plain = v.to_string();
                if plain.len() <= 20 {
                    f.write_str(&plain)
                } else {
                    write!(f, "{v:?}")
                }
            }
            // Non-finite constants (from folding, e.g. 1/0) as expressions that fold back.
            Node::Num(v) if v.is_nan() => f.write_str("(0/0)"),
            Node::Num(v) => f.write_str(if *v > 0.0 { "(1/0)" } else { "(-1/0)" }),
            Node::Var(i) => f.write_str(["x", "y", "z", "t"][*i as usize & 3]),
            Node::Un(Un::Neg, a) => {
                f.write_str("-")?;
                operand(f, a, a.binding() < 3)
            }
            Node::Un(g, a) => write!(f, "{}({a})", name_of(&UNARY_FUNCTIONS, *g)),
            Node::Bin(op @ (Bin::Atan2 | Bin::Min | Bin::Max), a, b) => {
                write!(f, "{}({a}, {b})", name_of(&BINARY_FUNCTIONS, *op))
            }
            Node::Bin(op, a, b) => {
                let (symbol, own) = match op {
                    Bin::Add => (" + ", 1),
                    Bin::Sub => (" - ", 1),
                    Bin::Mul => ("*", 2),
                    Bin::Div => ("/", 2),
                    _ => ("^", 4),
                };
                // `^` is right-associative with a primary base and a signed exponent; the
                // others are left-associative.
                let (left, right) = if own == 4 {
                    (a.binding() <= 4, b.binding() < 3)
                } else {
                    (a.binding() < own, b.binding() <= own)
                };
                operand(f, a, left)?;
                f.write_str(symbol)?;
                operand(f, b, right)
            }
        }
    }
}

/// One instruction of the compiled postfix program (flat, so the interpreter dispatches once per
/// instruction). `u8` operands are variable indices (0..3 = x, y, z, t).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Op {
    Const(f64),
    Var(u8),
    /// top = f(top)
    Un(Un),
    /// top = f(second, top); pops one value.
    Bin(Bin),
    /// top = top ^ n
    PowI(i32),
    /// top = top + c
    AddC(f64),
    /// top = top * c
    MulC(f64),
    /// top = c - top
    RSubC(f64),
    /// top = c / top
    RDivC(f64),
    /// top = top (op) variable
    AddV(u8),
    SubV(u8),
    MulV(u8),
    DivV(u8),
}

impl Op {
    fn is_binary(self) -> bool {
        matches!(self, Op::Bin(_))
    }
}

/// A compiled scalar expression in `x, y, z, t`. Two are equal when written and compiled the
/// same.
#[derive(Clone, PartialEq)]
pub struct Expr {
    src: String,
    ops: Box<[Op]>,
}

impl fmt::Debug for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Expr({:?})", self.src)
    }
}

impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.src)
    }
}

impl Expr {
    /// Compiles `src`. The error says what went wrong and at which (1-based) character column.
    pub fn parse(src: &str) -> std::result::Result<Expr, String> {
        let node = parse_tree(src)?;
        let mut ops = Vec::new();
        emit(&node, &mut ops);
        let depth = stack_depth(&ops);
        if depth > STACK {
            return Err(format!(
                "expression too complex: it needs {depth} stack slots (at most {STACK})"
            ));
        }
        Ok(Expr { src: src.to_string(), ops: ops.into_boxed_slice() })
    }

    /// The constant expression `value`.
    pub fn constant(value: f64) -> Expr {
        Expr { src: format!("{value}"), ops: vec![Op::Const(value)].into_boxed_slice() }
    }

    /// The constant expression 0.
    pub fn zero() -> Expr {
        Expr::constant(0.0)
    }

    /// The text the expression was compiled from.
    pub fn source(&self) -> &str {
        &self.src
    }

    /// Evaluates at point `x` and time `t`. Allocation-free.
    #[inline]
    pub fn eval(&self, x: [f64; 3], t: f64) -> f64 {
        // Fast path: a constant (the common case for zero loads / simple values).
        if let [Op::Const(c)] = *self.ops {
            return c;
        }
        self.run(&[x[0], x[1], x[2], t])
    }

    /// The interpreter: the top of the stack lives in `top` (a register), the rest in `st`.
    fn run(&self, v: &[f64; 4]) -> f64 {
        let mut st = [0.0f64; STACK];
        let mut sp = 0usize; // number of values in `st` (below `top`)
        let mut top = 0.0f64;
        for op in self.ops.iter() {
            match *op {
                Op::Const(c) => {
                    st[sp] = top;
                    sp += 1;
                    top = c;
                }
                Op::Var(i) => {
                    st[sp] = top;
                    sp += 1;
                    top = v[i as usize & 3];
                }
                Op::Un(f) => top = f.apply(top),
                Op::Bin(f) => {
                    sp -= 1;
                    top = f.apply(st[sp], top);
                }
                Op::PowI(n) => top = powi(top, n),
                Op::AddC(c) => top += c,
                Op::MulC(c) => top *= c,
                Op::RSubC(c) => top = c - top,
                Op::RDivC(c) => top = c / top,
                Op::AddV(i) => top += v[i as usize & 3],
                Op::SubV(i) => top -= v[i as usize & 3],
                Op::MulV(i) => top *= v[i as usize & 3],
                Op::DivV(i) => top /= v[i as usize & 3],
            }
        }
        top
    }

    fn uses_var(&self, pred: impl Fn(u8) -> bool) -> bool {
        self.ops.iter().any(|op| match *op {
            Op::Var(i) | Op::AddV(i) | Op::SubV(i) | Op::MulV(i) | Op::DivV(i) => pred(i),
            _ => false,
        })
    }

    /// Whether `t` survives constant folding (e.g. `0*t` still counts: no algebraic rewriting).
    pub fn depends_on_t(&self) -> bool {
        self.uses_var(|i| i == 3)
    }

    /// Whether any of `x`, `y`, `z` appears.
    pub fn depends_on_x(&self) -> bool {
        self.uses_var(|i| i < 3)
    }

    /// The value if the expression folded to a constant.
    pub fn as_constant(&self) -> Option<f64> {
        match *self.ops {
            [Op::Const(c)] => Some(c),
            _ => None,
        }
    }

    /// Whether the expression is (folds to) the literal constant 0, e.g. `"0"`, `"0.0"`, `"2-2"`.
    pub fn is_zero(&self) -> bool {
        self.as_constant() == Some(0.0)
    }
}

#[inline(always)]
fn powi(a: f64, n: i32) -> f64 {
    match n {
        2 => a * a,
        3 => a * a * a,
        _ => a.powi(n),
    }
}

/// A vector field: one expression per component; missing components evaluate to 0.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VecExpr(pub Vec<Expr>);

impl VecExpr {
    /// Evaluates the first three components (the rest, if any, are ignored).
    #[inline]
    pub fn eval(&self, x: [f64; 3], t: f64) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (o, e) in out.iter_mut().zip(self.0.iter()) {
            *o = e.eval(x, t);
        }
        out
    }

    /// Number of components given.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// No component given (which also means zero).
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Every component is the constant 0 (or there are none).
    pub fn is_zero(&self) -> bool {
        self.0.iter().all(Expr::is_zero)
    }

    pub fn depends_on_t(&self) -> bool {
        self.0.iter().any(Expr::depends_on_t)
    }

    pub fn depends_on_x(&self) -> bool {
        self.0.iter().any(Expr::depends_on_x)
    }
}

// ---------------------------------------------------------------------------------------------
// Lexer

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    Ident(String),
    Plus,
    Minus,
    Star,
    Slash,
    Caret,
    Open,
    Close,
    Comma,
    End,
}

#[derive(Debug, Clone)]
struct Token {
    tok: Tok,
    /// 1-based character column.
    col: usize,
    /// The text of the token, for messages.
    text: String,
}

fn lex(src: &str) -> std::result::Result<Vec<Token>, String> {
    let chars: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let col = i + 1;
        if c.is_whitespace() {
            i += 1;
            continue;
        }
        if c.is_ascii_digit() || (c == '.' && chars.get(i + 1).is_some_and(|d| d.is_ascii_digit()))
        {
            let start = i;
            while i < chars.len() && chars[i].is_ascii_digit() {
                i += 1;
            }
            if i < chars.len() && chars[i] == '.' {
                i += 1;
                while i < chars.len() && chars[i].is_ascii_digit() {
                    i += 1;
                }
            }
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                // An exponent only if digits follow (optionally signed); otherwise `e` is the
                // next token (and the parser reports it).
                let mut j = i + 1;
                if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
                    j += 1;
                }
                if j < chars.len() && chars[j].is_ascii_digit() {
                    i = j;
                    while i < chars.len() && chars[i].is_ascii_digit() {
                        i += 1;
                    }
                } else if j > i + 1 || j >= chars.len() || !is_ident_char(chars[j]) {
                    let text: String = chars[start..j].iter().collect();
                    return Err(format!("malformed number '{text}' at column {col}"));
                }
            }
            let text: String = chars[start..i].iter().collect();
            let v: f64 =
                text.parse().map_err(|_| format!("malformed number '{text}' at column {col}"))?;
            out.push(Token { tok: Tok::Num(v), col, text });
            continue;
        }
        if c.is_ascii_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && is_ident_char(chars[i]) {
                i += 1;
            }
            let text: String = chars[start..i].iter().collect();
            out.push(Token { tok: Tok::Ident(text.clone()), col, text });
            continue;
        }
        let tok = match c {
            '+' => Tok::Plus,
            '-' => Tok::Minus,
            '*' => {
                if chars.get(i + 1) == Some(&'*') {
                    return Err(format!(
                        "unexpected '**' at column {col} (write powers as a^b or pow(a, b))"
                    ));
                }
                Tok::Star
            }
            '/' => Tok::Slash,
            '^' => Tok::Caret,
            '(' => Tok::Open,
            ')' => Tok::Close,
            ',' => Tok::Comma,
            _ => return Err(format!("unexpected character '{c}' at column {col}")),
        };
        out.push(Token { tok, col, text: c.to_string() });
        i += 1;
    }
    out.push(Token { tok: Tok::End, col: chars.len() + 1, text: String::new() });
    Ok(out)
}

fn is_ident_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

// ---------------------------------------------------------------------------------------------
// Parser

/// Parses `src` into its constant-folded tree; the errors of [`Expr::parse`].
pub(super) fn parse_tree(src: &str) -> std::result::Result<Node, String> {
    let tokens = lex(src)?;
    let mut p = Parser { tokens, pos: 0, depth: 0 };
    if p.peek().tok == Tok::End {
        return Err("empty expression".to_string());
    }
    let node = p.expr()?;
    let t = p.peek();
    if t.tok != Tok::End {
        return Err(match t.tok {
            Tok::Close => format!("unmatched ')' at column {}", t.col),
            _ => p.unexpected(t),
        });
    }
    Ok(fold(node))
}

struct Parser {
    tokens: Vec<Token>,
    pos: usize,
    depth: usize,
}

type PResult = std::result::Result<Node, String>;

impl Parser {
    fn peek(&self) -> Token {
        self.tokens[self.pos].clone()
    }

    fn next(&mut self) -> Token {
        let t = self.tokens[self.pos].clone();
        if self.pos + 1 < self.tokens.len() {
            self.pos += 1;
        }
        t
    }

    fn unexpected(&self, t: Token) -> String {
        match t.tok {
            Tok::End => "unexpected end of expression".to_string(),
            Tok::Num(_) | Tok::Ident(_) | Tok::Open => {
                format!("unexpected '{}' at column {} (missing operator?)", t.text, t.col)
            }
            _ => format!("unexpected '{}' at column {}", t.text, t.col),
        }
    }

    fn enter(&mut self, col: usize) -> std::result::Result<(), String> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return Err(format!(
                "expression nested too deeply at column {col} (at most {MAX_NESTING} levels)"
            ));
        }
        Ok(())
    }

    fn expr(&mut self) -> PResult {
        self.left_assoc(&[(Tok::Plus, Bin::Add), (Tok::Minus, Bin::Sub)], Self::term)
    }

    fn term(&mut self) -> PResult {
        self.left_assoc(&[(Tok::Star, Bin::Mul), (Tok::Slash, Bin::Div)], Self::unary)
    }

    /// One precedence level of left-associative operators: `next (op next)*`.
    fn left_assoc(&mut self, ops: &[(Tok, Bin)], next: fn(&mut Self) -> PResult) -> PResult {
        let mut lhs = next(self)?;
        loop {
            let tok = self.peek().tok;
            let Some(&(_, op)) = ops.iter().find(|(t, _)| *t == tok) else { return Ok(lhs) };
            self.next();
            let rhs = next(self)?;
            lhs = Node::Bin(op, Box::new(lhs), Box::new(rhs));
        }
    }

    fn unary(&mut self) -> PResult {
        let t = self.peek();
        match t.tok {
            Tok::Minus | Tok::Plus => {
                self.next();
                self.enter(t.col)?;
                let inner = self.unary()?;
                self.depth -= 1;
                Ok(if t.tok == Tok::Minus { Node::Un(Un::Neg, Box::new(inner)) } else { inner })
            }
            _ => self.power(),
        }
    }

    fn power(&mut self) -> PResult {
        let base = self.primary()?;
        let t = self.peek();
        if t.tok == Tok::Caret {
            self.next();
            self.enter(t.col)?;
            // Right-associative, and the exponent may carry a sign: 2^-1, 2^3^2 = 2^9.
            let exp = self.unary()?;
            self.depth -= 1;
            return Ok(Node::Bin(Bin::Pow, Box::new(base), Box::new(exp)));
        }
        Ok(base)
    }

    fn primary(&mut self) -> PResult {
        let t = self.next();
        match t.tok {
            Tok::Num(v) => Ok(Node::Num(v)),
            Tok::Open => {
                self.enter(t.col)?;
                let inner = self.expr()?;
                self.depth -= 1;
                let c = self.next();
                if c.tok != Tok::Close {
                    return Err(match c.tok {
                        Tok::End => format!("missing ')' for the '(' at column {}", t.col),
                        _ => self.unexpected(c),
                    });
                }
                Ok(inner)
            }
            Tok::Ident(ref name) => {
                let is_call = self.peek().tok == Tok::Open;
                if is_call {
                    return self.call(name, t.col);
                }
                match name.as_str() {
                    "x" => Ok(Node::Var(0)),
                    "y" => Ok(Node::Var(1)),
                    "z" => Ok(Node::Var(2)),
                    "t" => Ok(Node::Var(3)),
                    "pi" => Ok(Node::Num(std::f64::consts::PI)),
                    "e" => Ok(Node::Num(std::f64::consts::E)),
                    n if Un::from_name(n).is_some() || Bin::from_name(n).is_some() => {
                        Err(format!("function '{n}' at column {} needs '(' and arguments", t.col))
                    }
                    n => Err(format!(
                        "unknown variable '{n}' at column {} (allowed: {VARIABLES})",
                        t.col
                    )),
                }
            }
            _ => Err(self.unexpected(t)),
        }
    }

    fn call(&mut self, name: &str, col: usize) -> PResult {
        let arity = if Un::from_name(name).is_some() {
            1
        } else if Bin::from_name(name).is_some() {
            2
        } else if matches!(name, "x" | "y" | "z" | "t" | "pi" | "e") {
            return Err(format!("'{name}' at column {col} is not a function (missing '*'?)"));
        } else {
            return Err(format!(
                "unknown function '{name}' at column {col} (allowed: {FUNCTIONS})"
            ));
        };
        let open = self.next(); // '('
        self.enter(open.col)?;
        let mut args = Vec::new();
        if self.peek().tok != Tok::Close {
            loop {
                args.push(self.expr()?);
                if self.peek().tok == Tok::Comma {
                    self.next();
                } else {
                    break;
                }
            }
        }
        self.depth -= 1;
        let c = self.next();
        if c.tok != Tok::Close {
            return Err(match c.tok {
                Tok::End => format!("missing ')' for the '(' at column {}", open.col),
                _ => self.unexpected(c),
            });
        }
        if args.len() != arity {
            return Err(format!(
                "function '{name}' at column {col} takes {arity} argument{}, got {}",
                if arity == 1 { "" } else { "s" },
                args.len()
            ));
        }
        let mut it = args.into_iter();
        let a = Box::new(it.next().unwrap_or(Node::Num(0.0)));
        Ok(match Un::from_name(name) {
            Some(f) => Node::Un(f, a),
            None => {
                let b = Box::new(it.next().unwrap_or(Node::Num(0.0)));
                Node::Bin(Bin::from_name(name).unwrap_or(Bin::Pow), a, b)
            }
        })
    }
}

// ---------------------------------------------------------------------------------------------
// Constant folding and code generation

fn fold(n: Node) -> Node {
    match n {
        Node::Un(f, a) => match fold(*a) {
            Node::Num(v) => Node::Num(f.apply(v)),
            a => Node::Un(f, Box::new(a)),
        },
        Node::Bin(f, a, b) => match (fold(*a), fold(*b)) {
            (Node::Num(x), Node::Num(y)) => Node::Num(f.apply(x, y)),
            (a, b) => Node::Bin(f, Box::new(a), Box::new(b)),
        },
        leaf => leaf,
    }
}

fn emit(n: &Node, ops: &mut Vec<Op>) {
    match n {
        Node::Num(v) => ops.push(Op::Const(*v)),
        Node::Var(i) => ops.push(Op::Var(*i)),
        Node::Un(f, a) => {
            emit(a, ops);
            ops.push(Op::Un(*f));
        }
        Node::Bin(f, a, b) => {
            // Fused forms with a leaf operand: one instruction instead of two.
            match (f, &**a, &**b) {
                (Bin::Pow, _, Node::Num(p)) if p.fract() == 0.0 && p.abs() <= 64.0 => {
                    emit(a, ops);
                    ops.push(Op::PowI(*p as i32));
                }
                (Bin::Add, _, Node::Num(c)) => {
                    emit(a, ops);
                    ops.push(Op::AddC(*c));
                }
                (Bin::Add, Node::Num(c), _) => {
                    emit(b, ops);
                    ops.push(Op::AddC(*c));
                }
                (Bin::Sub, _, Node::Num(c)) => {
                    emit(a, ops);
                    ops.push(Op::AddC(-*c));
                }
                (Bin::Sub, Node::Num(c), _) => {
                    emit(b, ops);
                    ops.push(Op::RSubC(*c));
                }
                (Bin::Mul, _, Node::Num(c)) => {
                    emit(a, ops);
                    ops.push(Op::MulC(*c));
                }
                (Bin::Mul, Node::Num(c), _) => {
                    emit(b, ops);
                    ops.push(Op::MulC(*c));
                }
                (Bin::Div, Node::Num(c), _) => {
                    emit(b, ops);
                    ops.push(Op::RDivC(*c));
                }
                (Bin::Add, _, Node::Var(i)) => {
                    emit(a, ops);
                    ops.push(Op::AddV(*i));
                }
                (Bin::Add, Node::Var(i), _) => {
                    emit(b, ops);
                    ops.push(Op::AddV(*i));
                }
                (Bin::Sub, _, Node::Var(i)) => {
                    emit(a, ops);
                    ops.push(Op::SubV(*i));
                }
                (Bin::Mul, _, Node::Var(i)) => {
                    emit(a, ops);
                    ops.push(Op::MulV(*i));
                }
                (Bin::Mul, Node::Var(i), _) => {
                    emit(b, ops);
                    ops.push(Op::MulV(*i));
                }
                (Bin::Div, _, Node::Var(i)) => {
                    emit(a, ops);
                    ops.push(Op::DivV(*i));
                }
                _ => {
                    emit(a, ops);
                    emit(b, ops);
                    ops.push(Op::Bin(*f));
                }
            }
        }
    }
}

fn stack_depth(ops: &[Op]) -> usize {
    let (mut sp, mut max) = (0usize, 0usize);
    for op in ops {
        match op {
            Op::Const(_) | Op::Var(_) => sp += 1,
            op if op.is_binary() => sp -= 1,
            _ => {}
        }
        max = max.max(sp);
    }
    max
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{E, PI};

    fn ev(s: &str, x: [f64; 3], t: f64) -> f64 {
        Expr::parse(s).unwrap_or_else(|e| panic!("{s}: {e}")).eval(x, t)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-13 * (1.0 + a.abs().max(b.abs()))
    }

    fn check(s: &str, x: [f64; 3], t: f64, want: f64) {
        let got = ev(s, x, t);
        assert!(close(got, want), "{s}: got {got}, want {want}");
    }

    fn err(s: &str) -> String {
        match Expr::parse(s) {
            Ok(e) => panic!("{s} parsed as {:?}", e.ops),
            Err(m) => m,
        }
    }

    const P: [f64; 3] = [1.5, -0.7, 2.25];

    #[test]
    fn numbers() {
        check("1", P, 0.0, 1.0);
        check("1.5", P, 0.0, 1.5);
        check("1e-3", P, 0.0, 1e-3);
        check("2.5E+2", P, 0.0, 250.0);
        check(".5", P, 0.0, 0.5);
        check("3.", P, 0.0, 3.0);
        check("pi", P, 0.0, PI);
        check("e", P, 0.0, E);
        check("  7 ", P, 0.0, 7.0);
    }

    #[test]
    fn precedence_and_associativity() {
        check("1+2*3", P, 0.0, 7.0);
        check("(1+2)*3", P, 0.0, 9.0);
        check("10-4-3", P, 0.0, 3.0);
        check("64/4/2", P, 0.0, 8.0);
        check("2^3^2", P, 0.0, 512.0);
        check("-2^2", P, 0.0, -4.0);
        check("(-2)^2", P, 0.0, 4.0);
        check("2^-1", P, 0.0, 0.5);
        check("-x^2", P, 0.0, -(1.5f64 * 1.5));
        check("2*-3", P, 0.0, -6.0);
        check("--3", P, 0.0, 3.0);
        check("+3-+2", P, 0.0, 1.0);
        check("2*3^2", P, 0.0, 18.0);
        check("-2*3", P, 0.0, -6.0);
        check("1-2+3", P, 0.0, 2.0);
        check("2/4*8", P, 0.0, 4.0);
        check("x^0.5", P, 0.0, 1.5f64.sqrt());
        check("y^3", P, 0.0, (-0.7f64).powi(3));
        check("x^-2", P, 0.0, 1.5f64.powi(-2));
    }

    #[test]
    fn variables_and_functions() {
        let [x, y, z] = P;
        let t = 0.3;
        check("x", P, t, x);
        check("y", P, t, y);
        check("z", P, t, z);
        check("t", P, t, t);
        check("sin(x)", P, t, x.sin());
        check("cos(y)", P, t, y.cos());
        check("tan(z)", P, t, z.tan());
        check("exp(t)", P, t, t.exp());
        check("log(x)", P, t, x.ln());
        check("sqrt(z)", P, t, z.sqrt());
        check("abs(y)", P, t, y.abs());
        check("sinh(x)", P, t, x.sinh());
        check("cosh(x)", P, t, x.cosh());
        check("tanh(x)", P, t, x.tanh());
        check("asin(t)", P, t, t.asin());
        check("acos(t)", P, t, t.acos());
        check("atan(x)", P, t, x.atan());
        check("atan2(y, x)", P, t, y.atan2(x));
        check("min(x, y)", P, t, x.min(y));
        check("max(x, y)", P, t, x.max(y));
        check("pow(x, 2.5)", P, t, x.powf(2.5));
        check("pow(2, 10)", P, t, 1024.0);
        check("sin(x)^2 + cos(x)^2", P, t, 1.0);
        check("exp(log(z))", P, t, z);
    }

    #[test]
    fn beam_expression_matches_rust() {
        let e = Expr::parse("0.02*x*(10-x)*y^2*sin(2*pi*t)").unwrap();
        for &(x, y, t) in &[(1.0, 0.5, 0.1), (3.7, -0.25, 0.013), (9.9, 1.0, 2.0)] {
            let want = 0.02 * x * (10.0 - x) * y * y * (2.0 * PI * t).sin();
            let got = e.eval([x, y, 0.0], t);
            assert!(close(got, want), "{got} vs {want}");
        }
        assert!(e.depends_on_t());
        assert!(e.depends_on_x());
        assert!(!e.is_zero());
    }

    #[test]
    fn constant_folding() {
        let e = Expr::parse("2*pi*3 + sin(0)").unwrap();
        assert_eq!(e.as_constant(), Some(6.0 * PI));
        assert!(Expr::parse("0").unwrap().is_zero());
        assert!(Expr::parse("0.0").unwrap().is_zero());
        assert!(Expr::parse("-0").unwrap().is_zero());
        assert!(Expr::parse("2-2").unwrap().is_zero());
        assert!(!Expr::parse("0*t").unwrap().is_zero()); // no algebraic rewriting
        assert!(!Expr::parse("1e-300").unwrap().is_zero());
        assert!(Expr::zero().is_zero());
        assert_eq!(Expr::constant(2.5).eval([0.0; 3], 0.0), 2.5);
        // Folding inside a larger expression: sin(2*pi*t) keeps one constant.
        let e = Expr::parse("sin(2*pi*t)").unwrap();
        assert_eq!(e.ops.len(), 3);
    }

    #[test]
    fn tree_text_parses_back_to_the_same_tree() {
        let srcs = [
            "x - (y - z)",
            "x*(y*z) + (x*y)*z",
            "x/(y/z) - x/y/z",
            "(x^2)^3 + 2^3^x + x^-2 + x^-y^2",
            "-x^2 + (-2)^x + -(x*y) - -y + --x",
            "-x*y + x*-y + x*-2.5 - (-3)*t",
            "atan2(y, x) + min(x, t)*max(1, z) + pow(x, y) + log(abs(sin(x + t)))",
            "1e-300*x + 1e300*y + 0.1*z + 2*t + -0*x",
            "1/0*x + (-1/0)*y + x^(1/0)",
            "0.08*pi^2*x*y^2*(x - 10) + 140/13*x*(x - 10) + 40/13*y^2",
        ];
        for src in srcs {
            let tree = parse_tree(src).unwrap();
            let text = tree.to_string();
            assert_eq!(parse_tree(&text).unwrap(), tree, "{src} -> {text}");
        }
        // NaN is not equal to itself: compare the texts.
        let nan = parse_tree("sqrt(-1)*x").unwrap().to_string();
        assert_eq!(nan, "(0/0)*x");
        assert_eq!(parse_tree(&nan).unwrap().to_string(), nan);
        assert_eq!(parse_tree("x - (y - 2*z)^2").unwrap().to_string(), "x - (y - 2*z)^2");
    }

    #[test]
    fn dependencies() {
        let e = Expr::parse("3*t").unwrap();
        assert!(e.depends_on_t() && !e.depends_on_x());
        let e = Expr::parse("z+1").unwrap();
        assert!(!e.depends_on_t() && e.depends_on_x());
        let e = Expr::parse("sin(pi)").unwrap();
        assert!(!e.depends_on_t() && !e.depends_on_x());
        let e = Expr::parse("1/y").unwrap();
        assert!(e.depends_on_x());
    }

    #[test]
    fn vec_expr() {
        let v = VecExpr(vec![Expr::parse("x").unwrap(), Expr::parse("t*2").unwrap()]);
        assert_eq!(v.eval([1.0, 2.0, 3.0], 4.0), [1.0, 8.0, 0.0]);
        assert!(!v.is_zero());
        assert!(v.depends_on_t());
        let z = VecExpr(vec![Expr::zero(), Expr::parse("0").unwrap()]);
        assert!(z.is_zero() && !z.depends_on_t());
        assert!(VecExpr::default().is_zero());
        assert_eq!(VecExpr::default().eval([1.0; 3], 1.0), [0.0; 3]);
    }

    #[test]
    fn error_messages() {
        assert_eq!(err("(1+2))"), "unmatched ')' at column 6");
        assert_eq!(err("1+)"), "unexpected ')' at column 3");
        assert_eq!(err("sin(x) * (2 + )"), "unexpected ')' at column 15");
        assert!(err("sinn(x)").starts_with("unknown function 'sinn' at column 1 (allowed: sin"));
        assert!(err("2*sinn(x)").contains("unknown function 'sinn' at column 3"));
        assert!(err("q + 1").starts_with("unknown variable 'q' at column 1 (allowed: x, y, z, t"));
        assert_eq!(err(""), "empty expression");
        assert_eq!(err("   "), "empty expression");
        assert_eq!(err("1+"), "unexpected end of expression");
        assert_eq!(err("(1+2"), "missing ')' for the '(' at column 1");
        assert_eq!(err("1 $ 2"), "unexpected character '$' at column 3");
        assert!(err("2x").contains("unexpected 'x' at column 2 (missing operator?)"));
        assert!(err("x(2)").contains("'x' at column 1 is not a function"));
        assert!(err("sin").contains("function 'sin' at column 1 needs '('"));
        assert_eq!(err("atan2(1)"), "function 'atan2' at column 1 takes 2 arguments, got 1");
        assert_eq!(err("sin(1, 2)"), "function 'sin' at column 1 takes 1 argument, got 2");
        assert_eq!(err("1e+"), "malformed number '1e+' at column 1");
        assert!(err("2**3").contains("'**' at column 2"));
        assert!(err("1,2").contains("unexpected ',' at column 2"));
        let deep = "(".repeat(500) + "1" + &")".repeat(500);
        assert!(err(&deep).contains("nested too deeply"));
        // Column counts characters, not bytes.
        assert!(err("1+é").contains("column 3"));
    }

    #[test]
    fn deep_but_legal_expressions() {
        // Left-leaning chains need little stack; right-leaning ones need more.
        let long = vec!["x"; 300].join("+");
        check(&long, P, 0.0, 300.0 * 1.5);
        let nested = "(".repeat(20) + "x" + &"+x)".repeat(20);
        check(&nested, P, 0.0, 21.0 * 1.5);
        let right = (0..40).map(|_| "(x+").collect::<String>() + "x" + &")".repeat(40);
        let r = Expr::parse(&right);
        // 40 pending left operands: either it fits or a clean error, never a panic.
        if let Ok(e) = r {
            assert!(close(e.eval(P, 0.0), 41.0 * 1.5));
        }
        let right2 = (0..40).map(|_| "(sin(x)+").collect::<String>() + "x" + &")".repeat(40);
        assert!(Expr::parse(&right2).unwrap_err().contains("too complex"));
    }
}
