// bench_wire: encode / decode throughput of Stripe frames of 1,000 points, and CRC-32C (SSE4.2 vs table).
// Bytes are payload bytes (48 + 12 * 1000 = 12,048 per frame); frames/s is items_per_second.
#include <benchmark/benchmark.h>

#include <vector>

#include "common/crc32c.hpp"
#include "common/wire.hpp"
#include "wire_samples.hpp"

namespace {

constexpr std::size_t kPoints = 1000;
constexpr std::size_t kFramesPerBatch = 64;

void BM_EncodeStripe1000(benchmark::State& state) {
  auto pts = fs::test::sample_points(kPoints);
  const fs::msg::Stripe m{fs::test::sample_stripe_header(7), pts};
  std::vector<std::uint8_t> out(fs::wire::frame_size(m));
  std::uint32_t seq = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(fs::wire::encode(out, seq++, m));
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations());
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * fs::wire::payload_size(m)));
  state.counters["hw_crc"] = fs::crc32c_using_hw();
}

// Feeds a stream of 64 frames in 64 KiB chunks (as from a socket) and decodes every Stripe into storage.
void decode_bench(benchmark::State& state, bool hw) {
  fs::crc32c_use_hw(hw);
  auto pts = fs::test::sample_points(kPoints);
  fs::wire::VectorSink sink;
  fs::wire::FrameWriter w(sink);
  for (std::uint32_t k = 0; k < kFramesPerBatch; ++k)
    w.send(fs::msg::Stripe{fs::test::sample_stripe_header(k), pts});
  std::vector<fs::msg::StripePoint> storage(fs::msg::kMaxStripePoints);
  fs::wire::FrameDecoder dec("bench");
  fs::msg::Stripe out;
  std::size_t frames = 0;
  for (auto _ : state) {
    std::span<const std::uint8_t> in(sink.data);
    while (!in.empty()) {
      in = in.subspan(dec.feed(in.first(std::min<std::size_t>(in.size(), 65536))));
      fs::wire::FrameView f;
      while (dec.next(f)) {
        fs::wire::decode(f, out, storage);
        benchmark::DoNotOptimize(out.points.data());
        ++frames;
      }
    }
  }
  if (frames != state.iterations() * kFramesPerBatch) state.SkipWithError("lost frames");
  state.SetItemsProcessed(static_cast<std::int64_t>(frames));
  state.SetBytesProcessed(static_cast<std::int64_t>(frames * (fs::wire::kStripeHeaderSize + 12 * kPoints)));
  state.counters["hw_crc"] = fs::crc32c_using_hw();
  fs::crc32c_use_hw(true);
}
void BM_DecodeStripe1000(benchmark::State& state) { decode_bench(state, true); }
void BM_DecodeStripe1000_TableCrc(benchmark::State& state) { decode_bench(state, false); }

void crc_bench(benchmark::State& state, std::uint32_t (*fn)(std::span<const std::uint8_t>, std::uint32_t)) {
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(state.range(0)));
  for (std::size_t i = 0; i < buf.size(); ++i) buf[i] = static_cast<std::uint8_t>(i * 131 + 7);
  for (auto _ : state) benchmark::DoNotOptimize(fn(buf, 0));
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * buf.size()));
}
void BM_Crc32cSse42(benchmark::State& state) {
  if (!fs::crc32c_hw_available()) {
    state.SkipWithError("no SSE4.2 on this CPU");
    return;
  }
  crc_bench(state, fs::crc32c_hw);
}
void BM_Crc32cTable(benchmark::State& state) { crc_bench(state, fs::crc32c_table); }

BENCHMARK(BM_EncodeStripe1000);
BENCHMARK(BM_DecodeStripe1000);
BENCHMARK(BM_DecodeStripe1000_TableCrc);
BENCHMARK(BM_Crc32cSse42)->Arg(12060)->Arg(1 << 20);
BENCHMARK(BM_Crc32cTable)->Arg(12060)->Arg(1 << 20);

}  // namespace

BENCHMARK_MAIN();
