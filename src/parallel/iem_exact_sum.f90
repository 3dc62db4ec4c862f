!> Exact summation of real(wp) terms, independent of their order and of how they are split
!> over ranks: each term is cut at its binary exponent into three 32-bit limbs on a fixed grid
!> and added to int64 bins that cover the whole double range, so no bit is ever lost; the
!> ranks' bins are combined with an integer MPI_Allreduce (associative), and value() rounds
!> the exact sum once, to nearest with ties to even (docs/numerics.md).
module iem_exact_sum
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_positive_inf, &
                                           ieee_negative_inf
  use mpi_f08, only: MPI_Comm, MPI_Allreduce, MPI_IN_PLACE, MPI_SUM
  use iem_kinds, only: wp, i8, mpi_i8
  implicit none
  private
  public :: exact_sum_t, exact_sum_allreduce, exact_sum_nbins, exact_sum_renorm_interval, &
            exact_sum_packed_size

  !> Bins: bin k holds limbs of weight 2**(32*k - 1074). A term's lowest bit lies at
  !> 2**-1074 .. 2**971, its three limbs reach bin 65; bins 66 and 67 take the carries of
  !> sums beyond the double range, and the last bin holds the sign (it is the only signed one
  !> after a normalisation).
  integer, parameter :: exact_sum_nbins = 68
  integer, parameter :: top = exact_sum_nbins - 1
  !> Terms added between two automatic normalisations: a normalised bin is below 2**32 and
  !> each term changes it by less than 2**32, so a bin stays below 2**32*(1 + 2**30) < 2**63.
  integer(i8), parameter :: exact_sum_renorm_interval = 2_i8**30
  integer(i8), parameter :: mask32 = 2_i8**32 - 1
  integer(i8), parameter :: hidden_bit = 2_i8**52
  !> Length of the packed state (pack/unpack, MPI): the normalised bins, then the counts of
  !> NaN, +Inf and -Inf terms.
  integer, parameter :: exact_sum_packed_size = exact_sum_nbins + 3
  integer, parameter :: n_packed = exact_sum_packed_size

  !> Exact accumulator of real(wp) terms: reset, add terms, merge or allreduce, then value().
  type :: exact_sum_t
    integer(i8) :: bin(0:top) = 0_i8
    !> Terms added since the bins were last normalised.
    integer(i8) :: n_pending = 0_i8
    !> Non-finite terms seen: they decide the result as in a plain sum.
    integer(i8) :: n_nan = 0_i8, n_pos_inf = 0_i8, n_neg_inf = 0_i8
  contains
    procedure :: reset => exact_sum_reset
    procedure :: add_scalar => exact_sum_add_scalar
    procedure :: add_array => exact_sum_add_array
    procedure :: add_scaled => exact_sum_add_scaled
    generic :: add => add_scalar, add_array
    procedure :: merge => exact_sum_merge
    procedure :: normalise => exact_sum_normalise
    procedure :: value => exact_sum_value
    procedure :: allreduce => exact_sum_allreduce_one
    procedure :: pack => exact_sum_pack
    procedure :: unpack => exact_sum_unpack
  end type exact_sum_t

contains

  !> Empty the accumulator (the exact sum becomes zero).
  pure subroutine exact_sum_reset(this)
    class(exact_sum_t), intent(inout) :: this
    this%bin = 0_i8
    this%n_pending = 0_i8
    this%n_nan = 0_i8
    this%n_pos_inf = 0_i8
    this%n_neg_inf = 0_i8
  end subroutine exact_sum_reset

  !> Add one term exactly.
  pure subroutine exact_sum_add_scalar(this, x)
    class(exact_sum_t), intent(inout) :: this
    real(wp), intent(in) :: x
    call deposit(this, x)
    this%n_pending = this%n_pending + 1
    if (this%n_pending >= exact_sum_renorm_interval) call this%normalise()
  end subroutine exact_sum_add_scalar

  !> Add every element of x exactly.
  pure subroutine exact_sum_add_array(this, x)
    class(exact_sum_t), intent(inout) :: this
    real(wp), intent(in) :: x(:)
    integer(i8) :: i, first, last, n
    n = size(x, kind=i8)
    first = 1
    do while (first <= n)
      ! as many terms as fit before the next normalisation
      last = min(n, first + (exact_sum_renorm_interval - this%n_pending) - 1)
      do i = first, last
        call deposit(this, x(i))
      end do
      this%n_pending = this%n_pending + (last - first + 1)
      if (this%n_pending >= exact_sum_renorm_interval) call this%normalise()
      first = last + 1
    end do
  end subroutine exact_sum_add_array

  !> Add w*x(i) for every element of x exactly (each product rounded as w*x(i) alone is):
  !> the same exact sum as add(w*x(i)) term by term, without a call a term.
  pure subroutine exact_sum_add_scaled(this, x, w)
    class(exact_sum_t), intent(inout) :: this
    real(wp), intent(in) :: x(:), w
    integer(i8) :: i, first, last, n
    n = size(x, kind=i8)
    first = 1
    do while (first <= n)
      last = min(n, first + (exact_sum_renorm_interval - this%n_pending) - 1)
      do i = first, last
        call deposit(this, w*x(i))
      end do
      this%n_pending = this%n_pending + (last - first + 1)
      if (this%n_pending >= exact_sum_renorm_interval) call this%normalise()
      first = last + 1
    end do
  end subroutine exact_sum_add_scaled

  !> The hot kernel: x = m * 2**(p - 1074), m the signed 53-bit integer significand, p >= 0
  !> the position of its lowest bit; m * 2**s (s = mod(p, 32)) is cut into two limbs in
  !> [0, 2**32) and a signed top limb, added to bins k = p/32, k+1, k+2. Branch-free but for
  !> Inf/NaN; no multiplication (a signed split costs less than multiplying by the sign).
  pure subroutine deposit(this, x)
    type(exact_sum_t), intent(inout) :: this
    real(wp), intent(in) :: x
    integer(i8) :: bits, m, t, neg
    integer :: e, p, k, s
    bits = transfer(x, 0_i8)
    e = int(ibits(bits, 52, 11))
    m = ibits(bits, 0, 52)
    if (e == 2047) then
      if (m /= 0_i8) then
        this%n_nan = this%n_nan + 1
      else if (bits < 0_i8) then
        this%n_neg_inf = this%n_neg_inf + 1
      else
        this%n_pos_inf = this%n_pos_inf + 1
      end if
      return
    end if
    ! normal numbers carry the hidden bit; subnormals (e = 0) share the exponent of e = 1
    if (e > 0) m = ior(m, hidden_bit)
    p = max(e, 1) - 1
    k = shiftr(p, 5)
    s = iand(p, 31)
    ! two's complement negation when the sign bit is set (neg = -1), else nothing (neg = 0)
    neg = shifta(bits, 63)
    m = ieor(m, neg) - neg
    ! m * 2**s = lo + 2**32 * t with lo the low 32 bits and t = floor(m * 2**s / 2**32);
    ! t = mid + 2**32 * hi likewise
    t = shifta(m, 32 - s)
    this%bin(k) = this%bin(k) + iand(shiftl(m, s), mask32)
    this%bin(k + 1) = this%bin(k + 1) + iand(t, mask32)
    this%bin(k + 2) = this%bin(k + 2) + shifta(t, 32)
  end subroutine deposit

  !> Propagate carries: every bin but the last in [0, 2**32), the last one signed. The exact
  !> sum is unchanged.
  pure subroutine exact_sum_normalise(this)
    class(exact_sum_t), intent(inout) :: this
    call carry(this%bin)
    this%n_pending = 0_i8
  end subroutine exact_sum_normalise

  !> Add the exact sum held by other to this one (exactly).
  pure subroutine exact_sum_merge(this, other)
    class(exact_sum_t), intent(inout) :: this
    type(exact_sum_t), intent(in) :: other
    integer(i8) :: b(0:top)
    b = other%bin
    call carry(b)
    call carry(this%bin)
    ! two normalised bins add to less than 2**33: far from overflow
    this%bin = this%bin + b
    call carry(this%bin)
    this%n_pending = 0_i8
    this%n_nan = this%n_nan + other%n_nan
    this%n_pos_inf = this%n_pos_inf + other%n_pos_inf
    this%n_neg_inf = this%n_neg_inf + other%n_neg_inf
  end subroutine exact_sum_merge

  !> Make this the exact sum over all ranks of comm of their accumulators. Collective.
  subroutine exact_sum_allreduce_one(this, comm)
    class(exact_sum_t), intent(inout) :: this
    type(MPI_Comm), intent(in) :: comm
    integer(i8) :: buf(n_packed)
    call this%pack(buf)
    call MPI_Allreduce(MPI_IN_PLACE, buf, n_packed, mpi_i8(), MPI_SUM, comm)
    call this%unpack(buf)
  end subroutine exact_sum_allreduce_one

  !> Make each sums(j) the exact sum over all ranks of comm of their sums(j), with one
  !> MPI_Allreduce for all of them. Collective; every rank passes the same size(sums).
  subroutine exact_sum_allreduce(sums, comm)
    type(exact_sum_t), intent(inout) :: sums(:)
    type(MPI_Comm), intent(in) :: comm
    integer(i8) :: buf(n_packed, size(sums))
    integer :: j
    do j = 1, size(sums)
      call sums(j)%pack(buf(:, j))
    end do
    call MPI_Allreduce(MPI_IN_PLACE, buf, size(buf), mpi_i8(), MPI_SUM, comm)
    do j = 1, size(sums)
      call sums(j)%unpack(buf(:, j))
    end do
  end subroutine exact_sum_allreduce

  !> The exact state as exact_sum_packed_size integers (normalised bins, non-finite counts),
  !> e.g. for a checkpoint; unpack restores it. Normalised bins are below 2**32, so the
  !> element-wise integer sum of fewer than 2**31 packed states cannot overflow.
  pure subroutine exact_sum_pack(this, buf)
    class(exact_sum_t), intent(in) :: this
    integer(i8), intent(out) :: buf(:)
    buf(1:exact_sum_nbins) = this%bin
    call carry(buf(1:exact_sum_nbins))
    buf(exact_sum_nbins + 1:n_packed) = [this%n_nan, this%n_pos_inf, this%n_neg_inf]
  end subroutine exact_sum_pack

  !> Set the state from buf, as written by pack (or an element-wise sum of packed states).
  pure subroutine exact_sum_unpack(this, buf)
    class(exact_sum_t), intent(inout) :: this
    integer(i8), intent(in) :: buf(:)
    this%bin = buf(1:exact_sum_nbins)
    call carry(this%bin)
    this%n_pending = 0_i8
    this%n_nan = buf(exact_sum_nbins + 1)
    this%n_pos_inf = buf(exact_sum_nbins + 2)
    this%n_neg_inf = buf(exact_sum_nbins + 3)
  end subroutine exact_sum_unpack

  !> The exact sum rounded to the nearest double, ties to even (so a function of the exact
  !> sum only): +Inf or -Inf when that rounding overflows; an exact zero gives +0. A NaN
  !> term, or both +Inf and -Inf terms, give NaN; otherwise an infinite term gives its Inf.
  pure function exact_sum_value(this) result(v)
    class(exact_sum_t), intent(in) :: this
    real(wp) :: v
    integer(i8) :: b(0:top)
    logical :: negative
    integer :: h

    if (this%n_nan > 0 .or. (this%n_pos_inf > 0 .and. this%n_neg_inf > 0)) then
      v = ieee_value(v, ieee_quiet_nan)
      return
    else if (this%n_pos_inf > 0) then
      v = ieee_value(v, ieee_positive_inf)
      return
    else if (this%n_neg_inf > 0) then
      v = ieee_value(v, ieee_negative_inf)
      return
    end if
    b = this%bin
    call carry(b)
    negative = b(top) < 0
    if (negative) then
      b = -b
      call carry(b)
    end if
    do h = top, 0, -1
      if (b(h) /= 0) exit
    end do
    if (h < 0) then
      v = 0.0_wp
      return
    end if
    v = round_magnitude(b, h)
    if (negative) v = -v
  end function exact_sum_value

  !> Round M = sum b(k)*2**(32k) (every b(k) in [0, 2**32), b(h) the highest nonzero) times
  !> 2**-1074 to the nearest double, ties to even.
  pure function round_magnitude(b, h) result(v)
    integer(i8), intent(in) :: b(0:)
    integer, intent(in) :: h
    real(wp) :: v
    integer :: nbit, q, d, e, k0
    integer(i8) :: w, m, rem, half
    logical :: sticky

    nbit = 32*h + (64 - leadz(b(h)))
    if (nbit <= 53) then
      ! M < 2**53: M * 2**-1074 is a double (subnormal or normal), no rounding
      m = b(0)
      if (h >= 1) m = ior(m, shiftl(b(1), 32))
      v = scale(real(m, wp), -1074)
      return
    end if
    ! the top (at most) 62 bits of M from bit q up, and whether any bit below q is set
    q = max(nbit - 62, 0)
    w = bit_field(b, q, nbit - q)
    k0 = q/32
    sticky = iand(b(k0), shiftl(1_i8, mod(q, 32)) - 1) /= 0 .or. any(b(0:k0 - 1) /= 0)
    ! keep 53 bits; d (1..9) bits go, rounded to nearest, ties to even
    d = nbit - q - 53
    m = shiftr(w, d)
    rem = iand(w, shiftl(1_i8, d) - 1)
    half = shiftl(1_i8, d - 1)
    if (rem > half .or. (rem == half .and. (sticky .or. btest(m, 0)))) m = m + 1
    e = nbit - 53 - 1074
    if (m == 2*hidden_bit) then
      m = hidden_bit
      e = e + 1
    end if
    if (e > maxexponent(v) - digits(v)) then
      v = ieee_value(v, ieee_positive_inf)
    else
      v = scale(real(m, wp), e)
    end if
  end function round_magnitude

  !> Bits q .. q+len-1 of M = sum b(k)*2**(32k), len <= 62.
  pure function bit_field(b, q, len) result(w)
    integer(i8), intent(in) :: b(0:)
    integer, intent(in) :: q, len
    integer(i8) :: w
    integer :: k, sh
    w = 0_i8
    do k = q/32, (q + len - 1)/32
      sh = 32*k - q
      if (sh >= 0) then
        w = ior(w, shiftl(b(k), sh))
      else
        w = ior(w, shiftr(b(k), -sh))
      end if
    end do
    w = iand(w, shiftl(1_i8, len) - 1)
  end function bit_field

  !> Carry propagation: b(k) = b(k) mod 2**32 with the floor quotient added to b(k+1).
  pure subroutine carry(b)
    integer(i8), intent(inout) :: b(0:)
    integer(i8) :: c
    integer :: k
    do k = 0, ubound(b, 1) - 1
      c = shifta(b(k), 32)
      b(k) = iand(b(k), mask32)
      b(k + 1) = b(k + 1) + c
    end do
  end subroutine carry
end module iem_exact_sum
