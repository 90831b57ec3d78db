// The words of an option's values: one table per enum, beside the enum's
// declaration, read by everything that turns words into values or back —
// the command line, job files, live requests, --help, error messages and
// reports. A new value is one new row; no parser or message to update.
//
//   inline constexpr Word<HitRule> kHitRuleWords[] = {
//       {"first", HitRule::first, "the first hit from the cage"},
//       {"nearest", HitRule::nearest, "the hit nearest to the low surface"},
//   };
//   NMBAKE_WORDS(HitRule, kHitRuleWords)
//
// then parse_word("nearest", rule), to_string(rule), expected_words<HitRule>().
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <string_view>

namespace nmbake {

// How a row is used: a word (read, listed, written), an alias (read only:
// "opengl" for up), or a value that is reported but never given (a cage
// mode of "mesh" means a cage file was given).
enum class WordUse : unsigned char { word, alias, reported };

template <class E>
struct Word {
  std::string_view word;
  E value;
  std::string_view help;  // one line, for --help and the reference
  WordUse use = WordUse::word;
};

// WordTable<E>::words is the table of E; NMBAKE_WORDS declares it.
template <class E>
struct WordTable;

#define NMBAKE_WORDS(Enum, table)                              \
  template <>                                                  \
  struct WordTable<Enum> {                                     \
    static constexpr std::span<const Word<Enum>> words{table}; \
  };

template <class E>
concept HasWords = requires {
  WordTable<E>::words;
};

// The value of `text` in `words` (words and aliases); false for any other text.
template <class E>
constexpr bool parse_word(std::span<const Word<E>> words, std::string_view text, E& out) {
  for (const Word<E>& w : words) {
    if (w.use != WordUse::reported && w.word == text) {
      out = w.value;
      return true;
    }
  }
  return false;
}
template <HasWords E>
constexpr bool parse_word(std::string_view text, E& out) {
  return parse_word(WordTable<E>::words, text, out);
}

// The word of `value` (its first row that is not an alias); "?" when the
// table has none, which a test rules out for every table.
template <class E>
constexpr const char* word_of(std::span<const Word<E>> words, E value) {
  for (const Word<E>& w : words) {
    if (w.use != WordUse::alias && w.value == value) return w.word.data();
  }
  return "?";
}
template <HasWords E>
constexpr const char* to_string(E value) {
  return word_of(WordTable<E>::words, value);
}

// The same for a table given by name (tables of bool, or a second table of
// one type).
template <class E, std::size_t N>
constexpr bool parse_word(const Word<E> (&words)[N], std::string_view text, E& out) {
  return parse_word(std::span<const Word<E>>(words), text, out);
}
template <class E, std::size_t N>
constexpr const char* word_of(const Word<E> (&words)[N], E value) {
  return word_of(std::span<const Word<E>>(words), value);
}

// on / off: the words of a switch given as a word (--dither on).
inline constexpr Word<bool> kOnOffWords[] = {
    {"on", true, "on"},
    {"off", false, "off"},
};

// "a, b or c": the words a user may give (aliases left out).
template <class E>
std::string word_list(std::span<const Word<E>> words, std::string_view last_separator = " or ") {
  std::string out;
  std::size_t count = 0, shown = 0;
  for (const Word<E>& w : words) count += w.use == WordUse::word ? 1 : 0;
  for (const Word<E>& w : words) {
    if (w.use != WordUse::word) continue;
    if (shown > 0) out += shown + 1 == count ? std::string(last_separator) : std::string(", ");
    out += w.word;
    ++shown;
  }
  return out;
}
template <class E, std::size_t N>
std::string word_list(const Word<E> (&words)[N], std::string_view last_separator = " or ") {
  return word_list(std::span<const Word<E>>(words), last_separator);
}
template <HasWords E>
std::string word_list(std::string_view last_separator = " or ") {
  return word_list(WordTable<E>::words, last_separator);
}

// "expected one of: a, b, c" — the one form of every unknown-word message.
template <class E>
std::string expected_words(std::span<const Word<E>> words) {
  return "expected one of: " + word_list(words, ", ");
}
template <class E, std::size_t N>
std::string expected_words(const Word<E> (&words)[N]) {
  return expected_words(std::span<const Word<E>>(words));
}
template <HasWords E>
std::string expected_words() {
  return expected_words(WordTable<E>::words);
}

}  // namespace nmbake
