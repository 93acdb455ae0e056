//! HTCondor ClassAd expressions, parsed far enough to know that a policy expression is
//! well formed and which attributes it reads: literals, attribute references (optionally
//! `MY.`/`TARGET.`), function calls, `!`, unary minus, `* / %`, `+ -`, comparisons
//! (`< <= > >= == != =?= =!=`), `&&`, `||` and `?:`, with HTCondor's precedence.

/// Attributes an expression reads, in order of appearance.
pub fn attributes(expr: &str) -> Result<Vec<String>, String> {
    let tokens = lex(expr)?;
    let mut p = Parser { tokens, at: 0, attributes: Vec::new() };
    p.ternary()?;
    if p.at != p.tokens.len() {
        return Err(format!("unexpected `{}` after a complete expression", p.tokens[p.at].text()));
    }
    Ok(p.attributes)
}

/// ClassAd functions these files may call (HTCondor manual, "ClassAd Syntax": predefined
/// functions).
const FUNCTIONS: &[&str] =
    &["time", "ifThenElse", "isUndefined", "isError", "isString", "int", "real", "floor"];
/// Literal keywords.
const KEYWORDS: &[&str] = &["true", "false", "undefined", "error"];

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Number,
    Str,
    Ident(String),
    Op(&'static str),
}

impl Tok {
    fn text(&self) -> String {
        match self {
            Tok::Number => "number".into(),
            Tok::Str => "string".into(),
            Tok::Ident(s) => s.clone(),
            Tok::Op(o) => (*o).into(),
        }
    }
}

/// Operators, longest first so that `=?=` wins over `=`.
const OPS: &[&str] = &[
    "=?=", "=!=", "&&", "||", "<=", ">=", "==", "!=", "<", ">", "!", "+", "-", "*", "/", "%", "(",
    ")", ",", "?", ":",
];

fn lex(s: &str) -> Result<Vec<Tok>, String> {
    let chars: Vec<char> = s.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit()
            || (c == '.' && chars.get(i + 1).is_some_and(char::is_ascii_digit))
        {
            while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '.') {
                i += 1;
            }
            out.push(Tok::Number);
        } else if c == '"' {
            let end = chars[i + 1..].iter().position(|&x| x == '"').ok_or("unterminated string")?;
            i += end + 2;
            out.push(Tok::Str);
        } else if c.is_ascii_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_alphanumeric() || "_.".contains(chars[i])) {
                i += 1;
            }
            out.push(Tok::Ident(chars[start..i].iter().collect()));
        } else {
            let rest: String = chars[i..].iter().take(3).collect();
            let op = OPS.iter().find(|op| rest.starts_with(**op)).ok_or(format!("bad `{c}`"))?;
            i += op.len();
            out.push(Tok::Op(op));
        }
    }
    Ok(out)
}

struct Parser {
    tokens: Vec<Tok>,
    at: usize,
    attributes: Vec<String>,
}

impl Parser {
    fn peek_op(&self, ops: &[&str]) -> Option<&'static str> {
        match self.tokens.get(self.at) {
            Some(Tok::Op(o)) if ops.contains(o) => Some(o),
            _ => None,
        }
    }

    fn expect(&mut self, op: &str) -> Result<(), String> {
        match self.peek_op(&[op]) {
            Some(_) => {
                self.at += 1;
                Ok(())
            }
            None => Err(format!("expected `{op}`")),
        }
    }

    fn ternary(&mut self) -> Result<(), String> {
        self.binary(0)?;
        if self.peek_op(&["?"]).is_some() {
            self.at += 1;
            self.ternary()?;
            self.expect(":")?;
            self.ternary()?;
        }
        Ok(())
    }

    /// Binary operators by level, loosest first.
    fn binary(&mut self, level: usize) -> Result<(), String> {
        const LEVELS: &[&[&str]] = &[
            &["||"],
            &["&&"],
            &["==", "!=", "=?=", "=!="],
            &["<", "<=", ">", ">="],
            &["+", "-"],
            &["*", "/", "%"],
        ];
        let Some(ops) = LEVELS.get(level) else { return self.unary() };
        self.binary(level + 1)?;
        while self.peek_op(ops).is_some() {
            self.at += 1;
            self.binary(level + 1)?;
        }
        Ok(())
    }

    fn unary(&mut self) -> Result<(), String> {
        if self.peek_op(&["!", "-", "+"]).is_some() {
            self.at += 1;
            return self.unary();
        }
        self.primary()
    }

    fn primary(&mut self) -> Result<(), String> {
        let tok = self.tokens.get(self.at).cloned().ok_or("expression ends too early")?;
        self.at += 1;
        match tok {
            Tok::Number | Tok::Str => Ok(()),
            Tok::Op("(") => {
                self.ternary()?;
                self.expect(")")
            }
            Tok::Ident(name) if self.peek_op(&["("]).is_some() => {
                if !FUNCTIONS.iter().any(|f| f.eq_ignore_ascii_case(&name)) {
                    return Err(format!("`{name}` is not a ClassAd function this check knows"));
                }
                self.at += 1;
                if self.peek_op(&[")"]).is_none() {
                    self.ternary()?;
                    while self.peek_op(&[","]).is_some() {
                        self.at += 1;
                        self.ternary()?;
                    }
                }
                self.expect(")")
            }
            Tok::Ident(name) => {
                if !KEYWORDS.iter().any(|k| k.eq_ignore_ascii_case(&name)) {
                    let bare = name
                        .strip_prefix("MY.")
                        .or_else(|| name.strip_prefix("TARGET."))
                        .unwrap_or(&name);
                    self.attributes.push(bare.to_string());
                }
                Ok(())
            }
            Tok::Op(op) => Err(format!("unexpected `{op}`")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn well_formed_expressions_yield_their_attributes() {
        assert_eq!(
            attributes("(LoadAvg - CondorLoadAvg) <= 0.3 && KeyboardIdle > (15 * 60)").unwrap(),
            ["LoadAvg", "CondorLoadAvg", "KeyboardIdle"]
        );
        assert_eq!(
            attributes("(time() - EnteredCurrentActivity) > 600").unwrap(),
            ["EnteredCurrentActivity"]
        );
        assert_eq!(
            attributes("Activity == \"Suspended\" ? True : MY.State =?= \"Claimed\"").unwrap(),
            ["Activity", "State"]
        );
    }

    #[test]
    fn malformed_expressions_are_refused() {
        for bad in [
            "(KeyboardIdle > 60",
            "KeyboardIdle >",
            "&& LoadAvg",
            "LoadAvg 3",
            "nosuch(1)",
            "a = b",
        ] {
            assert!(attributes(bad).is_err(), "{bad} accepted");
        }
    }
}
