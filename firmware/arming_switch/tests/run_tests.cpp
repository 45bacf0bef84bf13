// Runs every registered host test; exits non-zero when any check failed.
#include <iostream>

#include "check.h"

int main() {
  int passed = 0;
  int failed = 0;
  for (const check::Case& c : check::registry()) {
    const int before = check::failures();
    c.fn();
    const bool ok = check::failures() == before;
    std::cout << (ok ? "PASS " : "FAIL ") << c.name << "\n";
    if (ok) {
      ++passed;
    } else {
      ++failed;
    }
  }
  std::cout << passed << " passed, " << failed << " failed\n";
  return failed == 0 && passed > 0 ? 0 : 1;
}
