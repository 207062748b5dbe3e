// The object that carries the test programs' precompiled headers (tests/CMakeLists.txt, ssiu_test_pch):
// nothing of its own.
