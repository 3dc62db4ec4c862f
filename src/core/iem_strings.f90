!> Small string helpers for messages: numbers to text, lower case.
module iem_strings
  use iem_kinds, only: wp, i8
  implicit none
  private
  public :: itoa, rtoa, lower

  !> Integer to text without padding.
  interface itoa
    module procedure itoa_4, itoa_8
  end interface itoa

contains

  !> Default integer to text.
  pure function itoa_4(i) result(s)
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    character(len=16) :: b
    write(b, '(i0)') i
    s = trim(b)
  end function itoa_4

  !> 64-bit integer to text.
  pure function itoa_8(i) result(s)
    integer(i8), intent(in) :: i
    character(len=:), allocatable :: s
    character(len=24) :: b
    write(b, '(i0)') i
    s = trim(b)
  end function itoa_8

  !> Real to text with 6 significant digits.
  pure function rtoa(x) result(s)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=32) :: b
    if (x == 0.0_wp) then
      s = '0'
    else if (abs(x) >= 1.0e-3_wp .and. abs(x) < 1.0e6_wp) then
      write(b, '(g0.6)') x
      s = trim(adjustl(b))
    else
      write(b, '(es15.6e3)') x
      s = trim(adjustl(b))
    end if
  end function rtoa

  !> Lower-case copy of a string.
  pure function lower(s) result(t)
    character(len=*), intent(in) :: s
    character(len=len(s)) :: t
    integer :: k, c
    t = s
    do k = 1, len(s)
      c = iachar(s(k:k))
      if (c >= iachar('A') .and. c <= iachar('Z')) t(k:k) = achar(c + 32)
    end do
  end function lower
end module iem_strings
