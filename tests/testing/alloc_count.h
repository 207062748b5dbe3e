// Counts heap allocations, for the tests that prove a call allocates nothing (the flight core's rule:
// no heap after initialisation, docs/flight.md). Linking tests/testing/alloc_count.cc into a test
// program replaces the global operator new/delete (and, outside the sanitizer builds, whose runtime
// owns malloc, glibc's malloc/calloc/realloc) with counting versions that forward to the real ones.
//
//   ssiu::testing::AllocationCounter n;   // counts from here, this thread and every other
//   processor.OnFrames(...);
//   EXPECT_EQ(n.Count(), 0);
#pragma once

namespace ssiu::testing {

// True when malloc/calloc/realloc are counted too (false under AddressSanitizer, where only operator
// new is: the sanitizer's runtime defines malloc).
bool CountsMalloc();

class AllocationCounter {
 public:
  AllocationCounter();
  // Allocations (operator new of any form, and malloc/calloc/realloc where CountsMalloc()) since
  // construction or the last Reset().
  long Count() const;
  long Bytes() const;  // their requested bytes
  long Exceptions() const;  // C++ exceptions thrown (caught or not) since then
  void Reset();

 private:
  long count0_ = 0, bytes0_ = 0, throws0_ = 0;
};

}  // namespace ssiu::testing
