//! The syntax and meaning of one rule's expression: the lexer, a recursive-descent parser
//! (one function per grammar rule of the parent module's documentation), the type check of
//! each comparison, and the evaluation against a location.

use std::fmt;

use crate::omlox::{Location, ProviderType};

/// A property a rule may test (the spec's list).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Property {
    /// Horizontal accuracy, m.
    Accuracy,
    /// The provider's id.
    ProviderId,
    /// The provider type (`provider_type`).
    Type,
    /// The location's `source`.
    Source,
    /// The logical floor.
    Floor,
    /// Speed, m/s.
    Speed,
    /// Age at the evaluation time, ms.
    TimestampDiff,
}

impl Property {
    const ALL: [(&'static str, Self); 7] = [
        ("accuracy", Self::Accuracy),
        ("provider_id", Self::ProviderId),
        ("type", Self::Type),
        ("source", Self::Source),
        ("floor", Self::Floor),
        ("speed", Self::Speed),
        ("timestamp_diff", Self::TimestampDiff),
    ];

    fn named(name: &str) -> Option<Self> {
        Self::ALL
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))
            .map(|(_, p)| *p)
    }

    fn name(self) -> &'static str {
        Self::ALL.iter().find(|(_, p)| *p == self).map_or("?", |(n, _)| n)
    }

    /// Whether the property is a number (else text).
    fn numeric(self) -> bool {
        matches!(self, Self::Accuracy | Self::Floor | Self::Speed | Self::TimestampDiff)
    }
}

/// A comparison operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    /// `=`, `==`.
    Eq,
    /// `!=`, `<>`.
    Ne,
    /// `<`.
    Lt,
    /// `<=`.
    Le,
    /// `>`.
    Gt,
    /// `>=`.
    Ge,
}

/// A literal a property is compared with.
#[derive(Debug, Clone, PartialEq)]
pub enum Literal {
    /// A number.
    Number(f64),
    /// Text (quotes removed).
    Text(String),
}

/// A parsed condition.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    /// Both hold.
    And(Box<Expr>, Box<Expr>),
    /// Either holds.
    Or(Box<Expr>, Box<Expr>),
    /// It does not hold.
    Not(Box<Expr>),
    /// `property op literal`.
    Compare(Property, Op, Literal),
}

/// Why an expression does not parse: what, and where (1-based character position).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParseError {
    /// 1-based position of the offending character (one past the end when the expression
    /// stops too early).
    pub position: usize,
    /// What is wrong there.
    pub message: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "at character {}: {}", self.position, self.message)
    }
}

impl std::error::Error for ParseError {}

/// What a rule looks at: a location and its age at the evaluation time.
#[derive(Debug, Clone, Copy)]
pub struct Subject<'a> {
    /// The location.
    pub location: &'a Location,
    /// The evaluation time minus the location's time, ms.
    pub age_ms: f64,
}

impl Expr {
    /// Parses a rule's expression.
    ///
    /// # Errors
    /// [`ParseError`] with the position of the first fault.
    ///
    /// # Examples
    /// ```
    /// use rtls_server::omlox::locating_rules::Expr;
    /// assert!(Expr::parse("type = 'uwb' AND accuracy < 5").is_ok());
    /// let error = Expr::parse("accuracy <").unwrap_err();
    /// assert_eq!(error.position, 11);
    /// ```
    pub fn parse(text: &str) -> Result<Self, ParseError> {
        let tokens = lex(text)?;
        let mut parser = Parser {
            tokens,
            next: 0,
            end: text.chars().count() + 1,
        };
        let expr = parser.or()?;
        match parser.peek() {
            None => Ok(expr),
            Some((token, position)) => Err(ParseError {
                position,
                message: format!("unexpected {}: expected AND, OR or the end", token.describe()),
            }),
        }
    }

    /// Whether `subject` satisfies the condition.
    #[must_use]
    pub fn matches(&self, subject: &Subject<'_>) -> bool {
        match self {
            Self::And(a, b) => a.matches(subject) && b.matches(subject),
            Self::Or(a, b) => a.matches(subject) || b.matches(subject),
            Self::Not(a) => !a.matches(subject),
            Self::Compare(property, op, literal) => compare(*property, *op, literal, subject),
        }
    }
}

/// One comparison; false when the location does not carry the property.
fn compare(property: Property, op: Op, literal: &Literal, subject: &Subject<'_>) -> bool {
    let location = subject.location;
    match literal {
        Literal::Number(value) => {
            let actual = match property {
                Property::Accuracy => location.accuracy,
                Property::Floor => location.floor,
                Property::Speed => location.speed,
                Property::TimestampDiff => Some(subject.age_ms),
                Property::ProviderId | Property::Type | Property::Source => None,
            };
            actual.is_some_and(|actual| match op {
                Op::Eq => actual == *value,
                Op::Ne => actual != *value,
                Op::Lt => actual < *value,
                Op::Le => actual <= *value,
                Op::Gt => actual > *value,
                Op::Ge => actual >= *value,
            })
        }
        Literal::Text(value) => {
            let actual = match property {
                Property::ProviderId => location.provider_id.as_str(),
                Property::Type => location.provider_type.name(),
                Property::Source => location.source.as_str(),
                _ => return false,
            };
            match op {
                Op::Eq => actual == value,
                Op::Ne => actual != value,
                // refused by the parser
                _ => false,
            }
        }
    }
}

// ---- lexer ----

#[derive(Debug, Clone, PartialEq)]
enum Token {
    Word(String),
    Number(f64),
    Text(String),
    Op(Op),
    Open,
    Close,
}

impl Token {
    fn describe(&self) -> String {
        match self {
            Self::Word(w) => format!("`{w}`"),
            Self::Number(n) => format!("the number {n}"),
            Self::Text(t) => format!("the text '{t}'"),
            Self::Op(op) => format!("the operator {}", op_name(*op)),
            Self::Open => "`(`".into(),
            Self::Close => "`)`".into(),
        }
    }
}

fn op_name(op: Op) -> &'static str {
    match op {
        Op::Eq => "=",
        Op::Ne => "!=",
        Op::Lt => "<",
        Op::Le => "<=",
        Op::Gt => ">",
        Op::Ge => ">=",
    }
}

/// The tokens of `text`, each with its 1-based character position.
fn lex(text: &str) -> Result<Vec<(Token, usize)>, ParseError> {
    let chars: Vec<char> = text.chars().collect();
    let mut tokens = Vec::new();
    let mut i = 0;
    let error = |position: usize, message: String| ParseError { position, message };
    while i < chars.len() {
        let c = chars[i];
        let start = i + 1;
        if c.is_whitespace() {
            i += 1;
            continue;
        }
        let next = chars.get(i + 1).copied();
        let (token, length) = match c {
            '(' => (Token::Open, 1),
            ')' => (Token::Close, 1),
            '=' if next == Some('=') => (Token::Op(Op::Eq), 2),
            '=' => (Token::Op(Op::Eq), 1),
            '!' if next == Some('=') => (Token::Op(Op::Ne), 2),
            '<' if next == Some('>') => (Token::Op(Op::Ne), 2),
            '<' if next == Some('=') => (Token::Op(Op::Le), 2),
            '<' => (Token::Op(Op::Lt), 1),
            '>' if next == Some('=') => (Token::Op(Op::Ge), 2),
            '>' => (Token::Op(Op::Gt), 1),
            '\'' | '"' => {
                let mut value = String::new();
                let mut j = i + 1;
                loop {
                    match chars.get(j) {
                        None => return Err(error(start, format!("text opened with {c} is not closed"))),
                        Some(&q) if q == c && chars.get(j + 1) == Some(&c) => {
                            value.push(c);
                            j += 2;
                        }
                        Some(&q) if q == c => break,
                        Some(&other) => {
                            value.push(other);
                            j += 1;
                        }
                    }
                }
                (Token::Text(value), j + 1 - i)
            }
            c if c.is_ascii_digit()
                || c == '.'
                || (c == '-' && next.is_some_and(|n| n.is_ascii_digit() || n == '.')) =>
            {
                let mut j = i + 1;
                while let Some(&d) = chars.get(j) {
                    let exponent_sign = (d == '+' || d == '-') && matches!(chars[j - 1], 'e' | 'E');
                    if d.is_ascii_digit() || d == '.' || d == 'e' || d == 'E' || exponent_sign {
                        j += 1;
                    } else {
                        break;
                    }
                }
                let literal: String = chars[i..j].iter().collect();
                let value: f64 = literal
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| error(start, format!("`{literal}` is not a number")))?;
                (Token::Number(value), j - i)
            }
            c if c.is_alphabetic() || c == '_' => {
                let mut j = i + 1;
                while chars.get(j).is_some_and(|d| d.is_alphanumeric() || *d == '_') {
                    j += 1;
                }
                (Token::Word(chars[i..j].iter().collect()), j - i)
            }
            other => return Err(error(start, format!("unexpected character `{other}`"))),
        };
        tokens.push((token, start));
        i += length;
    }
    Ok(tokens)
}

// ---- parser (recursive descent, one function per grammar rule) ----

struct Parser {
    tokens: Vec<(Token, usize)>,
    next: usize,
    /// The position one past the last character (where a missing token is reported).
    end: usize,
}

impl Parser {
    fn peek(&self) -> Option<(&Token, usize)> {
        self.tokens.get(self.next).map(|(t, p)| (t, *p))
    }

    fn take(&mut self) -> Option<(Token, usize)> {
        let token = self.tokens.get(self.next).cloned();
        self.next += usize::from(token.is_some());
        token
    }

    /// Takes the keyword `word` (any case) if it is next.
    fn keyword(&mut self, word: &str) -> bool {
        let found = matches!(self.peek(), Some((Token::Word(w), _)) if w.eq_ignore_ascii_case(word));
        self.next += usize::from(found);
        found
    }

    fn or(&mut self) -> Result<Expr, ParseError> {
        let mut expr = self.and()?;
        while self.keyword("or") {
            expr = Expr::Or(Box::new(expr), Box::new(self.and()?));
        }
        Ok(expr)
    }

    fn and(&mut self) -> Result<Expr, ParseError> {
        let mut expr = self.not()?;
        while self.keyword("and") {
            expr = Expr::And(Box::new(expr), Box::new(self.not()?));
        }
        Ok(expr)
    }

    fn not(&mut self) -> Result<Expr, ParseError> {
        if self.keyword("not") {
            return Ok(Expr::Not(Box::new(self.not()?)));
        }
        match self.take() {
            Some((Token::Open, position)) => {
                let expr = self.or()?;
                match self.take() {
                    Some((Token::Close, _)) => Ok(expr),
                    Some((token, at)) => Err(ParseError {
                        position: at,
                        message: format!("expected `)` closing the `(` at {position}, found {}", token.describe()),
                    }),
                    None => Err(ParseError {
                        position: self.end,
                        message: format!("the `(` at {position} is not closed"),
                    }),
                }
            }
            Some((Token::Word(word), position)) => self.comparison(&word, position),
            Some((token, position)) => Err(ParseError {
                position,
                message: format!("expected a property, NOT or `(`, found {}", token.describe()),
            }),
            None => Err(ParseError {
                position: self.end,
                message: "expected a property, NOT or `(`".into(),
            }),
        }
    }

    fn comparison(&mut self, word: &str, position: usize) -> Result<Expr, ParseError> {
        let property = Property::named(word).ok_or_else(|| ParseError {
            position,
            message: format!(
                "unknown property `{word}`: one of {}",
                Property::ALL.map(|(n, _)| n).join(", ")
            ),
        })?;
        let op = match self.take() {
            Some((Token::Op(op), _)) => op,
            Some((token, at)) => {
                return Err(ParseError {
                    position: at,
                    message: format!("expected an operator after `{word}`, found {}", token.describe()),
                })
            }
            None => {
                return Err(ParseError {
                    position: self.end,
                    message: format!("expected an operator after `{word}`"),
                })
            }
        };
        let (literal, at) = match self.take() {
            Some((Token::Number(n), at)) => (Literal::Number(n), at),
            Some((Token::Text(t), at)) => (Literal::Text(t), at),
            Some((token, at)) => {
                return Err(ParseError {
                    position: at,
                    message: format!(
                        "expected a number or quoted text after {}, found {}",
                        op_name(op),
                        token.describe()
                    ),
                })
            }
            None => {
                return Err(ParseError {
                    position: self.end,
                    message: format!("expected a number or quoted text after {}", op_name(op)),
                })
            }
        };
        check_comparison(property, op, &literal).map_err(|message| ParseError { position: at, message })?;
        Ok(Expr::Compare(property, op, literal))
    }
}

/// A comparison's types: numbers with numbers, text with text by `=` / `!=`, `type` with a
/// provider type of the spec.
fn check_comparison(property: Property, op: Op, literal: &Literal) -> Result<(), String> {
    let name = property.name();
    match (property.numeric(), literal) {
        (true, Literal::Text(_)) => Err(format!("`{name}` is a number: compare it with a number")),
        (false, Literal::Number(_)) => Err(format!("`{name}` is text: compare it with quoted text")),
        (false, Literal::Text(_)) if !matches!(op, Op::Eq | Op::Ne) => Err(format!(
            "`{name}` is text: compare it with = or !=, not {}",
            op_name(op)
        )),
        (false, Literal::Text(value)) if property == Property::Type => {
            if ProviderType::ALL.iter().any(|t| t.name() == value) {
                Ok(())
            } else {
                Err(format!(
                    "`{value}` is not a provider type: one of {}",
                    ProviderType::ALL.map(ProviderType::name).join(", ")
                ))
            }
        }
        _ => Ok(()),
    }
}
