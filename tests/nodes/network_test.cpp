#include <doctest/doctest.h>

#include <stdexcept>

#include "nodes/network.h"

using namespace raynode::nodes;

TEST_CASE("network: the ipsc2 preset keeps the paper's figures in ray-times — 1 KiB at 0.9 MB/s, 2.75 MB/s peak") {
  // On a machine exactly as fast as the iPSC/2 the preset is the iPSC/2 itself.
  const NetworkModel real = make_network("ipsc2", kIpsc2SecondsPerRay);
  CHECK(real.scale == doctest::Approx(1.0));
  // A 1 KiB message: the sender's message software, then the wire.
  CHECK(real.send_overhead_s + real.message_time(1024, 0) == doctest::Approx(1024.0 / 0.9e6));
  CHECK(real.per_byte_s == doctest::Approx(1.0 / 2.75e6));
  CHECK(real.send_overhead_s == doctest::Approx(350e-6));  // the zero-byte latency (Arlauskas 1988)
  CHECK(real.latency_s == doctest::Approx(1024.0 / 0.9e6 - 1024.0 / 2.75e6 - 350e-6));
  CHECK(real.contention);
  // On a machine 10000x faster every cost shrinks 10000x: the page/ray ratio stays.
  const NetworkModel fast = make_network("ipsc2", kIpsc2SecondsPerRay / 1e4);
  CHECK(fast.message_time(1024, 1) / (kIpsc2SecondsPerRay / 1e4) ==
        doctest::Approx(real.message_time(1024, 1) / kIpsc2SecondsPerRay));
  CHECK(fast.send_overhead_s / (kIpsc2SecondsPerRay / 1e4) == doctest::Approx(real.send_overhead_s / kIpsc2SecondsPerRay));
  CHECK((real.send_overhead_s + real.message_time(1024, 0)) / kIpsc2SecondsPerRay ==
        doctest::Approx(0.138).epsilon(0.01));
  // Both ends of a page's transfer (the home's service, the faulting node's
  // own work) cost 0.1 ms on the iPSC/2, ~0.012 ray-times, at any speed.
  CHECK(real.service_s == doctest::Approx(100e-6));
  CHECK(real.fault_s == doctest::Approx(100e-6));
  CHECK(fast.fault_s / (kIpsc2SecondsPerRay / 1e4) == doctest::Approx(0.0121).epsilon(0.01));
}

TEST_CASE("network: none is free, cluster is unscaled, unknown names are refused") {
  const NetworkModel none = make_network("none");
  CHECK(none.message_time(1 << 20, 10) == 0.0);
  const NetworkModel cluster = make_network("cluster");
  CHECK(cluster.message_time(0, 0) == doctest::Approx(1.5e-6));
  CHECK(cluster.message_time(12500, 0) == doctest::Approx(1.5e-6 + 1e-6));
  CHECK_THROWS_AS(make_network("ethernet"), std::invalid_argument);
  // A fault's own work is left to the compute clock (the cost model's).
  CHECK(none.fault_s < 0);
  CHECK(cluster.fault_s < 0);
  // Neither charges a send's CPU or makes links contend.
  CHECK(none.send_overhead_s == 0);
  CHECK(cluster.send_overhead_s == 0);
  CHECK_FALSE(none.contention);
  CHECK_FALSE(cluster.contention);
}
