// Messages of the emulated network: a small fixed header plus a payload of
// plain bytes, copied into the receiver's mailbox as a network would copy
// them (docs/architecture.md, "Messages"; CONVENTIONS: trivially copyable structs that
// carry ids, never pointers).
//
// Place in the data flow: node code -> NodeContext::send(dest, payload) ->
// stamped MessageHeader + payload -> receiver's Mailbox -> NodeContext::receive
// -> Message (header + the bytes, read with `as<T>()`).
//
// Every kind of message in raynode has a MessageType, so the counters can
// report messages and bytes by type; each mode uses its own kinds.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <stdexcept>
#include <type_traits>

#include "nodes/arena.h"

namespace raynode::nodes {

/// Kinds of message.
enum class MessageType : std::uint16_t {
  kWorkRequest = 0,  ///< an idle node asks for work; travels the ring (work.h)
  kWorkGrant,        ///< a busy node gives a work item to the requester
  kPixels,           ///< finished pixels, node -> host
  kNodeDone,         ///< a node found no more work, node -> host
  kShutdown,         ///< the host ends the run, host -> node
  kPageRequest,      ///< svm: a page fault asks the home node for a page
  kPageReply,        ///< svm: the page's bytes
  kRay,              ///< dataflow: a ray sent to the owner of the next region
  kContribution,     ///< dataflow: a pixel contribution, node -> host
  kToken,            ///< termination-detection token
  kControl,          ///< other control messages (setup, statistics)
  kTest,             ///< tests and benchmarks
  kCount
};
inline constexpr std::size_t kMessageTypeCount = std::size_t(MessageType::kCount);

/// snake_case name of a message type, for counters and JSON ("page_request").
const char* message_type_name(MessageType type);

/// What travels ahead of the payload. `wire_bytes` is the size the message
/// would have on a real network (the cost model's byte count); by default
/// the payload size.
struct MessageHeader {
  MessageType type = MessageType::kTest;
  std::uint16_t reserved = 0;  ///< kRayCreditTag on a transport's ray credits (MachineState::ray_credits), else 0
  NodeId source = 0;
  std::uint32_t payload_bytes = 0;
  std::uint32_t wire_bytes = 0;
  double send_time = 0;     ///< sender's virtual time at departure, seconds
  double arrival_time = 0;  ///< virtual time at which it reaches the receiver, seconds
};
static_assert(std::is_trivially_copyable_v<MessageHeader>);
/// MessageHeader::reserved of a kControl message that returns ray credits
/// between processes (payload: one std::int32_t count). The transport's
/// delivery takes it; no participant sees it.
inline constexpr std::uint16_t kRayCreditTag = 0x5243;

/// A received message: the header and a view of its payload bytes, valid
/// until the receiver's next receive.
struct Message {
  MessageHeader header;
  std::span<const std::byte> payload;

  MessageType type() const { return header.type; }
  NodeId source() const { return header.source; }
  /// The payload as a T (copied out; T trivially copyable). Throws
  /// std::logic_error if the payload is shorter than T.
  template <class T>
  T as() const {
    static_assert(std::is_trivially_copyable_v<T>);
    if (payload.size() < sizeof(T)) throw std::logic_error("message payload shorter than its type");
    T t;
    std::memcpy(&t, payload.data(), sizeof(T));
    return t;
  }
  /// The bytes after a leading T (a variable-length tail such as a page or pixels).
  template <class T>
  std::span<const std::byte> tail() const {
    return payload.size() <= sizeof(T) ? std::span<const std::byte>() : payload.subspan(sizeof(T));
  }
};

}  // namespace raynode::nodes
