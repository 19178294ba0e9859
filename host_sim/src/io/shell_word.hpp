#pragma once
// Command lines printed for a user to paste into a shell (the studies' --list-cases, the
// truths' simulate lines).
#include <string>

namespace bms {

// Single quotes unless the word is plainly safe.
inline std::string shell_word(const std::string& w) {
  if (!w.empty() && w.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-+=.,/:") ==
                        std::string::npos)
    return w;
  std::string q = "'";
  for (char ch : w) q += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
  return q + "'";
}

}  // namespace bms
