#include "io/expression.hpp"

#include <fmt/format.h>

#include <array>
#include <charconv>
#include <cmath>

#include "io/input_error.hpp"

namespace bms {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kE = 2.71828182845904523536;
constexpr double kLn10 = 2.30258509299404568402;

bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_name_start(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; }
bool is_name_char(char c) { return is_name_start(c) || is_digit(c); }

std::string describe(char c) {
  if (c > ' ' && c < 127) return fmt::format("'{}'", c);
  return fmt::format("byte 0x{:02x}", static_cast<unsigned char>(c));
}

}  // namespace

// Python's grammar, restricted to what BPX functions use:
//   expression := term (('+' | '-') term)*
//   term       := factor (('*' | '/') factor)*
//   factor     := ('+' | '-') factor | power       (so -x**2 is -(x**2))
//   power      := primary ['**' factor]            (right-associative: 2**3**2 = 2**9)
//   primary    := number | 'x' | 'pi' | 'e' | function '(' expression ')' | '(' expression ')'
class ExpressionFunction::Parser {
 public:
  Parser(std::string_view text, std::string_view where) : text_(text), where_(where) {}

  std::vector<Instruction> run() {
    skip_space();
    if (pos_ == text_.size()) fail("empty expression");
    expression();
    skip_space();
    if (pos_ != text_.size()) fail("unexpected " + describe(text_[pos_]));
    return std::move(program_);
  }

 private:
  // Every recursive path goes through factor(), so guarding it bounds the C++ stack.
  class DepthGuard {
   public:
    explicit DepthGuard(Parser& p) : p_(p) {
      if (++p_.depth_ > kMaxDepth) {
        p_.fail(fmt::format("expression nested too deeply (more than {} levels)", kMaxDepth));
      }
    }
    ~DepthGuard() { --p_.depth_; }
    DepthGuard(const DepthGuard&) = delete;
    DepthGuard& operator=(const DepthGuard&) = delete;

   private:
    Parser& p_;
  };

  void expression() {
    term();
    for (;;) {
      skip_space();
      if (accept('+')) {
        term();
        emit(Op::add);
      } else if (accept('-')) {
        term();
        emit(Op::subtract);
      } else {
        return;
      }
    }
  }

  void term() {
    factor();
    for (;;) {
      skip_space();
      if (looking_at("//")) fail("unsupported operator '//'");
      if (accept('*')) {
        factor();
        emit(Op::multiply);
      } else if (accept('/')) {
        factor();
        emit(Op::divide);
      } else {
        return;
      }
    }
  }

  void factor() {
    DepthGuard guard(*this);
    skip_space();
    if (accept('-')) {
      factor();
      emit(Op::negate);
    } else if (accept('+')) {
      factor();
    } else {
      power();
    }
  }

  void power() {
    primary();
    skip_space();
    if (looking_at("**")) {
      pos_ += 2;
      factor();
      emit(Op::power);
    }
  }

  void primary() {
    skip_space();
    if (pos_ == text_.size()) fail("unexpected end of expression");
    const char c = text_[pos_];
    if (is_digit(c) || (c == '.' && pos_ + 1 < text_.size() && is_digit(text_[pos_ + 1]))) {
      number();
    } else if (is_name_start(c)) {
      name();
    } else if (accept('(')) {
      expression();
      expect_close();
    } else {
      fail("unexpected " + describe(c));
    }
  }

  void number() {
    const std::size_t start = pos_;
    digits();
    if (pos_ < text_.size() && text_[pos_] == '.') {
      ++pos_;
      digits();
    }
    if (pos_ < text_.size() && (text_[pos_] == 'e' || text_[pos_] == 'E')) {
      std::size_t p = pos_ + 1;
      if (p < text_.size() && (text_[p] == '+' || text_[p] == '-')) ++p;
      if (p < text_.size() && is_digit(text_[p])) {
        pos_ = p;
        digits();
      }
    }
    // "2x", "1_000", "1.2.3", "3e" are Python syntax errors too.
    if (pos_ < text_.size() && (is_name_char(text_[pos_]) || text_[pos_] == '.')) {
      fail_at(start, "invalid number");
    }
    double v = 0.0;
    const char* first = text_.data() + start;
    const char* last = text_.data() + pos_;
    const auto [end, ec] = std::from_chars(first, last, v);
    if (ec == std::errc::result_out_of_range) fail_at(start, "number out of range");
    if (ec != std::errc() || end != last) fail_at(start, "invalid number");
    emit(Op::constant, v);
  }

  void name() {
    const std::size_t start = pos_;
    while (pos_ < text_.size() && is_name_char(text_[pos_])) ++pos_;
    const std::string_view id = text_.substr(start, pos_ - start);
    if (id == "x") return emit(Op::variable);
    if (id == "pi") return emit(Op::constant, kPi);
    if (id == "e") return emit(Op::constant, kE);
    const Op op = function(id, start);
    skip_space();
    if (!accept('(')) fail(fmt::format("expected '(' after function '{}'", id));
    expression();
    expect_close();
    emit(op);
  }

  Op function(std::string_view id, std::size_t start) {
    static constexpr std::pair<std::string_view, Op> kFunctions[] = {
        {"exp", Op::exp},   {"log", Op::log},   {"log10", Op::log10}, {"sqrt", Op::sqrt},
        {"tanh", Op::tanh}, {"sinh", Op::sinh}, {"cosh", Op::cosh},   {"abs", Op::abs}};
    for (const auto& [n, op] : kFunctions) {
      if (n == id) return op;
    }
    std::size_t p = pos_;
    while (p < text_.size() && (text_[p] == ' ' || text_[p] == '\t')) ++p;
    const bool called = p < text_.size() && text_[p] == '(';
    fail_at(start, fmt::format("unknown {} '{}' (the variable is 'x'; functions: exp, log, "
                               "log10, sqrt, tanh, sinh, cosh, abs)",
                               called ? "function" : "name", id));
  }

  void digits() {
    while (pos_ < text_.size() && is_digit(text_[pos_])) ++pos_;
  }
  void skip_space() {
    while (pos_ < text_.size() && (text_[pos_] == ' ' || text_[pos_] == '\t' ||
                                   text_[pos_] == '\n' || text_[pos_] == '\r')) {
      ++pos_;
    }
  }
  bool looking_at(std::string_view s) const { return text_.substr(pos_, s.size()) == s; }
  bool accept(char c) {
    if (pos_ < text_.size() && text_[pos_] == c && !(c == '*' && looking_at("**"))) {
      ++pos_;
      return true;
    }
    return false;
  }
  void expect_close() {
    skip_space();
    if (accept(')')) return;
    if (pos_ == text_.size()) fail("missing ')'");
    fail("expected ')' but found " + describe(text_[pos_]));
  }

  void emit(Op op, double constant = 0.0) {
    program_.push_back({op, constant});
    if (op == Op::constant || op == Op::variable) {
      if (++stack_ > max_stack_) max_stack_ = stack_;
      if (max_stack_ > kMaxStack) fail("expression too complex");
    } else if (op == Op::add || op == Op::subtract || op == Op::multiply || op == Op::divide ||
               op == Op::power) {
      --stack_;
    }
  }

  [[noreturn]] void fail(const std::string& problem) const { fail_at(pos_, problem); }
  [[noreturn]] void fail_at(std::size_t pos, const std::string& problem) const {
    throw InputError(fmt::format("{}: {} at column {}", where_, problem, pos + 1));
  }

  std::string_view text_;
  std::string_view where_;
  std::size_t pos_ = 0;
  int depth_ = 0;
  std::vector<Instruction> program_;
  std::size_t stack_ = 0;
  std::size_t max_stack_ = 0;
};

std::shared_ptr<const ExpressionFunction> ExpressionFunction::parse(std::string_view text,
                                                                    std::string_view where) {
  if (text.size() > kMaxLength) {
    throw InputError(fmt::format("{}: expression longer than {} characters ({})", where, kMaxLength,
                                 text.size()));
  }
  return std::shared_ptr<const ExpressionFunction>(
      new ExpressionFunction(std::string(text), Parser(text, where).run()));
}

namespace {

// Chain-rule product that keeps constant subexpressions exact: 0 * inf would be NaN.
double chain(double df_du, double du) { return du == 0.0 ? 0.0 : df_du * du; }

}  // namespace

// One-argument operations on the top of the stack; false when op takes two arguments.
bool ExpressionFunction::apply_unary(Op op, ValueAndDerivative& u) {
  switch (op) {
    case Op::negate:
      u = {-u.value, -u.derivative};
      return true;
    case Op::exp: {
      const double v = std::exp(u.value);
      u = {v, chain(v, u.derivative)};
      return true;
    }
    case Op::log:
      u = {std::log(u.value), chain(1.0 / u.value, u.derivative)};
      return true;
    case Op::log10:
      u = {std::log10(u.value), chain(1.0 / (u.value * kLn10), u.derivative)};
      return true;
    case Op::sqrt: {
      const double v = std::sqrt(u.value);
      u = {v, chain(0.5 / v, u.derivative)};
      return true;
    }
    case Op::tanh: {
      const double v = std::tanh(u.value);
      u = {v, chain(1.0 - v * v, u.derivative)};
      return true;
    }
    case Op::sinh:
      u = {std::sinh(u.value), chain(std::cosh(u.value), u.derivative)};
      return true;
    case Op::cosh:
      u = {std::cosh(u.value), chain(std::sinh(u.value), u.derivative)};
      return true;
    case Op::abs: {
      const double sign = u.value > 0.0 ? 1.0 : (u.value < 0.0 ? -1.0 : 0.0);
      u = {std::fabs(u.value), chain(sign, u.derivative)};
      return true;
    }
    default:
      return false;
  }
}

// Two-argument operations: a = a op b.
void ExpressionFunction::apply_binary(Op op, ValueAndDerivative& a, const ValueAndDerivative& b) {
  switch (op) {
    case Op::add:
      a = {a.value + b.value, a.derivative + b.derivative};
      break;
    case Op::subtract:
      a = {a.value - b.value, a.derivative - b.derivative};
      break;
    case Op::multiply:
      a = {a.value * b.value, chain(b.value, a.derivative) + chain(a.value, b.derivative)};
      break;
    case Op::divide: {
      const double q = a.value / b.value;
      a = {q, (a.derivative - chain(q, b.derivative)) / b.value};
      break;
    }
    case Op::power: {
      // d(a^b) = b a^(b-1) a' + a^b ln(a) b'; the ln term only when the exponent varies,
      // so x**2 stays defined for x <= 0.
      double p, dp_da;
      const double e = b.value;
      if (b.derivative == 0.0 && (e == 2.0 || e == 3.0)) {  // common in BPX fits; pow is slow
        const double a2 = a.value * a.value;
        p = e == 2.0 ? a2 : a2 * a.value;
        dp_da = e == 2.0 ? 2.0 * a.value : 3.0 * a2;
      } else {
        p = std::pow(a.value, e);
        dp_da = a.value != 0.0 ? e * p / a.value : e * std::pow(a.value, e - 1.0);
      }
      const double d = chain(dp_da, a.derivative) + chain(p * std::log(a.value), b.derivative);
      a = {p, d};
      break;
    }
    default:
      break;
  }
}

ExpressionFunction::ValueAndDerivative ExpressionFunction::evaluate(double x) const {
  using D = ValueAndDerivative;
  std::array<D, kMaxStack> stack;
  std::size_t top = 0;
  for (const Instruction& in : program_) {
    if (in.op == Op::constant) {
      stack[top++] = {in.constant, 0.0};
      continue;
    }
    if (in.op == Op::variable) {
      stack[top++] = {x, 1.0};
      continue;
    }
    if (apply_unary(in.op, stack[top - 1])) continue;
    const D b = stack[--top];
    apply_binary(in.op, stack[top - 1], b);
  }
  return stack[0];
}

}  // namespace bms
