// ThreadSanitizer suppressions linked into the DDS test programs: Cyclone DDS (libddsc) is
// not built with TSan, so its own lock-free hand-offs (receive threads, delivery queues)
// look like races to TSan. Only reports with a libddsc frame are suppressed; races in
// simgate's own code are still reported. (Same line as in tests/tsan.supp for CI.)
extern "C" const char* __tsan_default_suppressions() { return "race:libddsc.so\n"; }
