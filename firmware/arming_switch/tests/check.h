// A minimal test runner for the host tests: no framework to download.
// TEST(name) registers a test; CHECK/CHECK_EQ record failures and keep going.
#pragma once

#include <iostream>
#include <string>
#include <vector>

namespace check {

struct Case {
  const char* name;
  void (*fn)();
};

inline std::vector<Case>& registry() {
  static std::vector<Case> cases;
  return cases;
}

inline int& failures() {
  static int n = 0;
  return n;
}

struct Register {
  Register(const char* name, void (*fn)()) { registry().push_back(Case{name, fn}); }
};

inline void fail(const char* file, int line, const std::string& what) {
  ++failures();
  std::cout << "    " << file << ":" << line << ": " << what << "\n";
}

}  // namespace check

#define TEST(name)                                         \
  static void name();                                      \
  static const check::Register name##_registered(#name, name); \
  static void name()

#define CHECK(cond)                                                      \
  do {                                                                   \
    if (!(cond)) check::fail(__FILE__, __LINE__, "CHECK(" #cond ")");    \
  } while (0)

#define CHECK_EQ(a, b)                                                                     \
  do {                                                                                     \
    const auto check_a_ = (a);                                                             \
    const auto check_b_ = (b);                                                             \
    if (!(check_a_ == check_b_)) {                                                         \
      check::fail(__FILE__, __LINE__,                                                      \
                  "CHECK_EQ(" #a ", " #b "): " + std::to_string(+check_a_) + " != " +      \
                      std::to_string(+check_b_));                                          \
    }                                                                                      \
  } while (0)
