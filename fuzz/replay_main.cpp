// Runs a libFuzzer harness without libFuzzer, so every `make test` (and the asan preset)
// exercises it with the ordinary compiler: each seed as it is, then a fixed number of
// deterministic mutations of the seeds (byte flips, insertions of tokens parsers trip on,
// deletions, duplications, truncations, splices). A crash, a trap in the harness's own checks
// or an exception the harness lets through fails the test; the failing input is written out
// so that it can be replayed (`NAME_replay --input FILE`) or given to the libFuzzer build.
//
//   NAME_replay [--iterations N] [--seed S] [--input FILE] [--crash-dir DIR] CORPUS...
//
// CORPUS is a file or a folder of seed files (large seeds are cut to their first 8 KiB:
// mutating a whole 500 KB trajectory teaches nothing a prefix does not).
#include <algorithm>
#include <array>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <string_view>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

// A harness may add seeds that are easier to build in code than to keep as files (binary
// messages); libFuzzer never calls it, a corpus folder serves there.
using AddSeedFn = void (*)(const std::uint8_t* data, std::size_t size);
extern "C" __attribute__((weak)) void KestrelFuzzSeeds(AddSeedFn add);

namespace {

using Bytes = std::vector<std::uint8_t>;
constexpr std::size_t kMaxSeedBytes = 8 * 1024;
constexpr std::size_t kMaxInputBytes = 64 * 1024;

std::vector<Bytes> g_seeds;
const Bytes* g_current = nullptr;
std::string g_crash_dir = ".";

// splitmix64: tiny, seedable, the same sequence on every platform.
struct Rng {
  std::uint64_t s;
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  std::size_t below(std::size_t n) { return n == 0 ? 0 : static_cast<std::size_t>(next() % n); }
};

// Tokens that reach the corners of text parsers: number edge cases, separators, comments,
// YAML and JSON structure, PNG chunk names.
constexpr std::array<std::string_view, 32> kTokens = {
    "nan",   "-nan",       "inf",       "-inf",
    "1e309", "-1e-320",    "0x1p3",     "18446744073709551616",
    "-0",    "9999999999", " ",         "\t",
    "\n",    "\r\n",       ",",         "#",
    ":",     "- ",         "[",         "]",
    "{",     "}",          "\"",        "'",
    "null",  "true",       "[1, 2, 3]", "~",
    "IHDR",  "IEND",       "\xff",      std::string_view("\0", 1)};

Bytes mutate(const Bytes& seed, Rng& rng) {
  Bytes b = seed;
  const int ops = 1 + static_cast<int>(rng.below(4));
  for (int k = 0; k < ops; ++k) {
    switch (rng.below(7)) {
      case 0:  // flip bits of one byte
        if (!b.empty()) b[rng.below(b.size())] ^= static_cast<std::uint8_t>(1u << rng.below(8));
        break;
      case 1: {  // insert a token
        const std::string_view t = kTokens[rng.below(kTokens.size())];
        b.insert(b.begin() + static_cast<std::ptrdiff_t>(rng.below(b.size() + 1)), t.begin(),
                 t.end());
        break;
      }
      case 2: {  // delete a range
        if (b.empty()) break;
        const std::size_t at = rng.below(b.size());
        const std::size_t n = 1 + rng.below(std::min<std::size_t>(b.size() - at, 64));
        b.erase(b.begin() + static_cast<std::ptrdiff_t>(at),
                b.begin() + static_cast<std::ptrdiff_t>(at + n));
        break;
      }
      case 3: {  // duplicate a range (repeated lines, repeated stamps)
        if (b.empty()) break;
        const std::size_t at = rng.below(b.size());
        const std::size_t n = 1 + rng.below(std::min<std::size_t>(b.size() - at, 256));
        const Bytes piece(b.begin() + static_cast<std::ptrdiff_t>(at),
                          b.begin() + static_cast<std::ptrdiff_t>(at + n));
        b.insert(b.begin() + static_cast<std::ptrdiff_t>(rng.below(b.size() + 1)), piece.begin(),
                 piece.end());
        break;
      }
      case 4:  // truncate (a file cut off mid-write)
        b.resize(rng.below(b.size() + 1));
        break;
      case 5:  // overwrite one byte with an arbitrary value
        if (!b.empty()) b[rng.below(b.size())] = static_cast<std::uint8_t>(rng.next());
        break;
      default: {  // splice the tail of another seed
        const Bytes& other = g_seeds[rng.below(g_seeds.size())];
        if (other.empty()) break;
        const std::size_t cut = rng.below(b.size() + 1);
        const std::size_t from = rng.below(other.size());
        b.resize(cut);
        b.insert(b.end(), other.begin() + static_cast<std::ptrdiff_t>(from), other.end());
        break;
      }
    }
    if (b.size() > kMaxInputBytes) b.resize(kMaxInputBytes);
  }
  return b;
}

void write_current(const char* why) {
  if (g_current == nullptr) return;
  const std::string path = g_crash_dir + "/crash-input.bin";
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(g_current->data()),
            static_cast<std::streamsize>(g_current->size()));
  std::fprintf(stderr, "fuzz replay: %s on a %zu-byte input, written to %s\n", why,
               g_current->size(), path.c_str());
}

void on_terminate() {
  write_current("uncaught exception");
  std::abort();
}

#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
// Installed only without a sanitizer (main), whose own handler reports the fault with a stack.
void on_signal(int sig) {
  write_current(sig == SIGSEGV ? "SIGSEGV" : sig == SIGILL ? "SIGILL (trap)" : "signal");
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}
#endif

void run(const Bytes& input) {
  g_current = &input;
  // An empty vector's data() may be null; libFuzzer always passes a valid pointer.
  static const std::uint8_t kEmpty = 0;
  LLVMFuzzerTestOneInput(input.empty() ? &kEmpty : input.data(), input.size());
  g_current = nullptr;
}

bool read_file(const std::filesystem::path& p, Bytes& out) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return false;
  out.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return true;
}

void add_seed(const std::uint8_t* data, std::size_t size) {
  g_seeds.emplace_back(data, data + std::min(size, kMaxSeedBytes));
}

int usage(const char* argv0) {
  std::fprintf(stderr,
               "usage: %s [--iterations N] [--seed S] [--input FILE] [--crash-dir DIR] "
               "CORPUS...\n",
               argv0);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  long iterations = 2000;
  std::uint64_t seed = 1;
  std::vector<std::string> corpus;
  std::string single;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--iterations" && has_value) {
      iterations = std::strtol(argv[++i], nullptr, 10);
    } else if (a == "--seed" && has_value) {
      seed = std::strtoull(argv[++i], nullptr, 10);
    } else if (a == "--input" && has_value) {
      single = argv[++i];
    } else if (a == "--crash-dir" && has_value) {
      g_crash_dir = argv[++i];
    } else if (!a.empty() && a[0] == '-') {
      return usage(argv[0]);
    } else {
      corpus.emplace_back(a);
    }
  }
  std::set_terminate(on_terminate);
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
  // Under a sanitizer its own handler reports the fault with a stack; ours would hide it.
  std::signal(SIGSEGV, on_signal);
  std::signal(SIGILL, on_signal);
  std::signal(SIGFPE, on_signal);
  std::signal(SIGABRT, on_signal);
#endif

  if (!single.empty()) {
    Bytes b;
    if (!read_file(single, b)) {
      std::fprintf(stderr, "fuzz replay: cannot read %s\n", single.c_str());
      return 2;
    }
    run(b);
    std::printf("fuzz replay: %s ran clean\n", single.c_str());
    return 0;
  }

  for (const std::string& c : corpus) {
    std::vector<std::filesystem::path> files;
    std::error_code ec;
    if (std::filesystem::is_directory(c, ec)) {
      for (const auto& e : std::filesystem::directory_iterator(c)) {
        if (e.is_regular_file()) files.push_back(e.path());
      }
    } else {
      files.emplace_back(c);
    }
    std::sort(files.begin(), files.end());  // the same order, so the same mutations, everywhere
    for (const auto& f : files) {
      Bytes b;
      if (!read_file(f, b)) {
        std::fprintf(stderr, "fuzz replay: cannot read seed %s\n", f.string().c_str());
        return 2;
      }
      add_seed(b.data(), b.size());
    }
  }
  if (KestrelFuzzSeeds != nullptr) KestrelFuzzSeeds(add_seed);
  if (g_seeds.empty()) {
    std::fprintf(stderr, "fuzz replay: no seeds (give a corpus file or folder)\n");
    return 2;
  }

  for (const Bytes& s : g_seeds) run(s);
  Rng rng{seed};
  for (long i = 0; i < iterations; ++i) {
    const Bytes m = mutate(g_seeds[rng.below(g_seeds.size())], rng);
    run(m);
  }
  std::printf("fuzz replay: %zu seeds and %ld mutations ran clean\n", g_seeds.size(), iterations);
  return 0;
}
