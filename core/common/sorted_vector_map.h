#pragma once
// A map kept as one vector of (key, value) sorted by key: the subset of
// std::map's interface that small, often-walked maps need (a map point's
// observers: tens of entries, walked by tracking for every tracked point each
// frame). Walking is a pass over contiguous memory instead of a tree's nodes;
// inserting and erasing move the entries after the position, which is cheap at
// these sizes. Iteration is in key order, as std::map's. Iterators and
// references are invalidated by insertion and erasure.
#include <algorithm>
#include <cstddef>
#include <utility>
#include <vector>

namespace orbatlas {

template <class Key, class Value>
class SortedVectorMap {
 public:
  using value_type = std::pair<Key, Value>;
  using iterator = typename std::vector<value_type>::iterator;
  using const_iterator = typename std::vector<value_type>::const_iterator;

  iterator begin() { return entries_.begin(); }
  iterator end() { return entries_.end(); }
  const_iterator begin() const { return entries_.begin(); }
  const_iterator end() const { return entries_.end(); }
  std::size_t size() const { return entries_.size(); }
  bool empty() const { return entries_.empty(); }

  iterator find(const Key& key) {
    const iterator it = lower_bound(key);
    return it != entries_.end() && it->first == key ? it : entries_.end();
  }
  const_iterator find(const Key& key) const {
    const const_iterator it = lower_bound(key);
    return it != entries_.end() && it->first == key ? it : entries_.end();
  }
  bool contains(const Key& key) const { return find(key) != entries_.end(); }

  // As std::map::emplace: inserts when `key` is absent; the bool says whether it did.
  std::pair<iterator, bool> emplace(const Key& key, Value value) {
    const iterator it = lower_bound(key);
    if (it != entries_.end() && it->first == key) return {it, false};
    return {entries_.insert(it, value_type(key, std::move(value))), true};
  }
  iterator erase(const_iterator it) { return entries_.erase(it); }

 private:
  iterator lower_bound(const Key& key) {
    return std::lower_bound(entries_.begin(), entries_.end(), key,
                            [](const value_type& e, const Key& k) { return e.first < k; });
  }
  const_iterator lower_bound(const Key& key) const {
    return std::lower_bound(entries_.begin(), entries_.end(), key,
                            [](const value_type& e, const Key& k) { return e.first < k; });
  }

  std::vector<value_type> entries_;
};

}  // namespace orbatlas
