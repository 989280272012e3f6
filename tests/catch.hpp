#pragma once
// Catch2 v3 where installed, Debian's v2.13 otherwise; tests are written against the common API.
#if __has_include(<catch2/catch_all.hpp>)
#include <catch2/catch_all.hpp>
using Catch::Approx;
#else
#include <catch2/catch.hpp>
#endif
