#pragma once
// Small text helpers for one-line messages and parsers.
#include <string>
#include <string_view>

namespace specula {

/// Shortest round-trip text of v as a stream prints it (420, 0.5, 1e-09), for messages.
std::string num(double v);
/// s cut to max characters (then "...") with control characters shown as '?', safe in a one-line message.
std::string printable(std::string_view s, std::size_t max = 60);
/// s without leading and trailing white space (space, tab, CR, LF, FF, VT).
std::string_view trim(std::string_view s);
/// s with ASCII letters in lower case.
std::string lower(std::string_view s);
/// s trimmed, with every run of spaces and tabs inside it made one space ("a  b\tc" -> "a b c").
std::string collapse_spaces(std::string_view s);

}  // namespace specula
