!> The bytes of an image file seen through a bounded buffer (for iem_image): any byte by its
!> position in the file, read from the file in chunks of at most buffer_bytes on demand
!> (stream access, pos=), so a reader never holds the whole file. Bytes already in memory (a
!> string) are served the same way.
module iem_image_bytes
  use iem_kinds, only: i8
  implicit none
  private
  public :: image_bytes_t, buffer_bytes

  !> Most bytes of a file held at once (1 MiB).
  integer, parameter :: buffer_bytes = 1048576

  !> The bytes 1..n of a file (open on unit) or of a string (held in buf); the buffer holds
  !> bytes base + 1 .. base + have. The first failed read is kept in ios, iom; it reads as
  !> NULs.
  type :: image_bytes_t
    logical :: file = .false.
    integer :: unit = 0
    integer(i8) :: n = 0, base = 0
    integer :: have = 0
    character(len=:), allocatable :: buf
    integer :: ios = 0
    character(len=256) :: iom = ''
  contains
    procedure :: attach_file, attach_string, at
  end type image_bytes_t

contains

  !> Serve the n bytes of the file open on unit (stream access); nothing is read yet.
  subroutine attach_file(this, unit, n)
    class(image_bytes_t), intent(inout) :: this
    integer, intent(in) :: unit
    integer(i8), intent(in) :: n
    this%file = .true.
    this%unit = unit
    this%n = n
    this%base = 0
    this%have = 0
    this%ios = 0
    if (allocated(this%buf)) deallocate(this%buf)
    allocate(character(len=int(max(min(n, int(buffer_bytes, i8)), 1_i8))) :: this%buf)
  end subroutine attach_file

  !> Serve the bytes of a string (held whole, as given).
  subroutine attach_string(this, bytes)
    class(image_bytes_t), intent(inout) :: this
    character(len=*), intent(in) :: bytes
    this%file = .false.
    this%n = len(bytes, kind=i8)
    this%base = 0
    this%buf = bytes
    this%have = len(bytes)
    this%ios = 0
  end subroutine attach_string

  !> The byte at position p (1..n), reading the buffer from p on when p is outside it; a NUL
  !> when it cannot be read (ios is then set).
  function at(this, p) result(c)
    class(image_bytes_t), intent(inout) :: this
    integer(i8), intent(in) :: p
    character(len=1) :: c
    integer :: m, ios
    character(len=256) :: iom
    if (p <= this%base .or. p > this%base + this%have) then
      c = achar(0)
      if (.not. this%file .or. p < 1 .or. p > this%n) return
      this%base = p - 1
      this%have = 0
      m = int(min(int(len(this%buf), i8), this%n - this%base))
      read(this%unit, pos=p, iostat=ios, iomsg=iom) this%buf(1:m)
      if (ios /= 0) then
        if (this%ios == 0) then
          this%ios = ios
          this%iom = iom
        end if
        return
      end if
      this%have = m
    end if
    c = this%buf(p - this%base:p - this%base)
  end function at
end module iem_image_bytes
