#pragma once

#include <type_traits>
#include <utility>

namespace clutterseg::core {

template <typename Signature>
class FunctionRef;

/// A non-owning reference to a callable (a lambda, a function object, a std::function): two
/// pointers, never allocates. The referenced callable must outlive every call through it, so
/// use it only as a parameter of a function that calls it before returning.
///
/// Thread-safety: calling is as safe as calling the referenced callable.
template <typename R, typename... Args>
class FunctionRef<R(Args...)> {
 public:
  template <typename F, typename = std::enable_if_t<!std::is_same_v<std::decay_t<F>, FunctionRef> &&
                                                    std::is_invocable_r_v<R, F&, Args...>>>
  FunctionRef(F&& f) noexcept  // NOLINT(google-explicit-constructor): stands in for a callable
      : object_(const_cast<void*>(static_cast<const void*>(std::addressof(f)))),
        call_([](void* object, Args... args) -> R {
          return (*static_cast<std::remove_reference_t<F>*>(object))(std::forward<Args>(args)...);
        }) {}

  R operator()(Args... args) const { return call_(object_, std::forward<Args>(args)...); }

 private:
  void* object_;
  R (*call_)(void*, Args...);
};

}  // namespace clutterseg::core
