#include <doctest/doctest.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <thread>
#include <vector>

#include "nodes/mailbox.h"

using namespace raynode::nodes;

namespace {

struct Item {
  std::uint32_t producer;
  std::uint32_t seq;
  std::uint64_t check;  // a function of the two, to catch torn copies
};

bool push_item(Mailbox& box, const Item& item, std::size_t tail_bytes = 0) {
  std::vector<std::byte> tail(tail_bytes, std::byte(item.seq & 0xff));
  const std::span<const std::byte> parts[2] = {std::as_bytes(std::span<const Item, 1>(&item, 1)), tail};
  MessageHeader h;
  h.type = MessageType::kTest;
  h.source = item.producer;
  return box.try_push(h, parts);
}

std::uint64_t check_of(std::uint32_t p, std::uint32_t s) { return (std::uint64_t(p) << 32 | s) * 0x9E3779B97F4A7C15ull; }

}  // namespace

TEST_CASE("mailbox: FIFO order, and a full mailbox refuses without changing anything") {
  Arena arena(0, 1 << 20);
  Mailbox box(arena, 4, 64);
  CHECK(box.capacity() == 4);
  CHECK(arena.used() == box.bytes());
  for (std::uint32_t i = 0; i < 4; ++i) CHECK(push_item(box, Item{0, i, check_of(0, i)}));
  CHECK_FALSE(push_item(box, Item{0, 99, 0}));  // full
  CHECK(box.approximate_size() == 4);
  CHECK(box.claimed() == 4);  // the refused push claimed nothing
  std::vector<std::byte> buf(64);
  MessageHeader h;
  for (std::uint32_t i = 0; i < 4; ++i) {
    REQUIRE(box.try_pop(h, buf.data()));
    Item it;
    std::memcpy(&it, buf.data(), sizeof it);
    CHECK(it.seq == i);
    CHECK(h.payload_bytes == sizeof(Item));
    CHECK(box.claimed() == (i == 0 ? 3u : 4u - i));  // one pushed back in after the first pop
    if (i == 0) CHECK(push_item(box, Item{0, 4, check_of(0, 4)}));  // room again after one pop
  }
  REQUIRE(box.try_pop(h, buf.data()));
  Item it;
  std::memcpy(&it, buf.data(), sizeof it);
  CHECK(it.seq == 4);  // the one refused before never got in
  CHECK_FALSE(box.try_pop(h, buf.data()));
  CHECK(box.claimed() == 0);
}

TEST_CASE("mailbox: a payload larger than the slot is refused with an error, capacity rounds to a power of two") {
  Arena arena(0, 1 << 20);
  Mailbox box(arena, 5, 16);
  CHECK(box.capacity() == 8);
  CHECK_THROWS_AS(push_item(box, Item{0, 0, 0}, 1), std::length_error);  // 16 + 1 bytes
  std::vector<std::byte> buf(16);
  MessageHeader h;
  CHECK_FALSE(box.try_pop(h, buf.data()));
}

TEST_CASE("mailbox: the slots come out of the owner's arena, and a too-small arena refuses the mailbox") {
  Arena small(7, 1000);
  CHECK_THROWS_AS(Mailbox(small, 64, 1024), ArenaExhausted);
  CHECK(small.used() == 0);
}

TEST_CASE("mailbox: 6 producers, one blocking consumer: every message arrives once, whole, in per-producer order") {
  constexpr std::uint32_t kProducers = 6, kPerProducer = 20000;
  Arena arena(0, 1 << 24);
  Mailbox box(arena, 64, 128);
  std::atomic<bool> stop{false};
  std::vector<std::thread> producers;
  for (std::uint32_t p = 0; p < kProducers; ++p)
    producers.emplace_back([&, p] {
      for (std::uint32_t s = 0; s < kPerProducer; ++s) {
        const Item it{p, s, check_of(p, s)};
        while (!push_item(box, it, (s % 5) * 13)) std::this_thread::yield();
      }
    });
  std::vector<std::uint32_t> next(kProducers, 0);
  std::vector<std::byte> buf(128);
  std::uint64_t received = 0, bad = 0;
  MessageHeader h;
  while (received < std::uint64_t(kProducers) * kPerProducer) {
    if (!box.try_pop(h, buf.data())) {
      box.wait(stop);
      continue;
    }
    Item it;
    std::memcpy(&it, buf.data(), sizeof it);
    bad += it.producer >= kProducers || h.source != it.producer || it.check != check_of(it.producer, it.seq);
    if (it.producer < kProducers) {
      bad += it.seq != next[it.producer];
      next[it.producer] = it.seq + 1;
    }
    bad += h.payload_bytes != sizeof(Item) + (it.seq % 5) * 13;
    for (std::uint32_t i = sizeof(Item); i < h.payload_bytes; ++i) bad += buf[i] != std::byte(it.seq & 0xff);
    ++received;
  }
  for (auto& t : producers) t.join();
  CHECK(bad == 0);
  for (std::uint32_t p = 0; p < kProducers; ++p) CHECK(next[p] == kPerProducer);
  CHECK_FALSE(box.try_pop(h, buf.data()));
}

TEST_CASE("mailbox: a waiting consumer is woken by a late message and by a stop request") {
  Arena arena(0, 1 << 20);
  Mailbox box(arena, 8, 32);
  std::atomic<bool> stop{false};
  std::thread producer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    push_item(box, Item{1, 7, check_of(1, 7)});
  });
  std::vector<std::byte> buf(32);
  MessageHeader h;
  while (!box.try_pop(h, buf.data())) box.wait(stop);
  producer.join();
  CHECK(h.source == 1);
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    stop.store(true);
    box.wake();
  });
  while (!stop.load()) box.wait(stop);  // would hang if the wake-up were lost
  stopper.join();
  CHECK_FALSE(box.try_pop(h, buf.data()));
}

TEST_CASE("mailbox: a quiet wait returns at once on a message or a stop, on wake(), and by its timeout") {
  Arena arena(0, 1 << 20);
  Mailbox box(arena, 8, 32);
  std::atomic<bool> stop{false};
  std::vector<std::byte> buf(32);
  MessageHeader h;
  using clock = std::chrono::steady_clock;
  auto seconds_of = [&](auto&& f) {
    const auto t0 = clock::now();
    f();
    return std::chrono::duration<double>(clock::now() - t0).count();
  };
  // A message already there: no 30 s nap.
  REQUIRE(push_item(box, Item{2, 1, check_of(2, 1)}));
  CHECK(seconds_of([&] { box.wait_quietly(stop, 30.0); }) < 10.0);
  REQUIRE(box.try_pop(h, buf.data()));
  // Empty: the timeout ends it (a generous bound: the point is that it ends).
  CHECK(seconds_of([&] { box.wait_quietly(stop, 0.01); }) < 10.0);
  // wake() (how a run is stopped) ends a 30 s quiet wait.
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    stop.store(true);
    box.wake();
  });
  CHECK(seconds_of([&] {
          while (!stop.load()) box.wait_quietly(stop, 30.0);
        }) < 10.0);
  stopper.join();
  CHECK(seconds_of([&] { box.wait_quietly(stop, 30.0); }) < 10.0);  // stop already set
}
