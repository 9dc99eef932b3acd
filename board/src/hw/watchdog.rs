//! The independent watchdog (IWDG), as the firmware update uses it: the bootloader starts it
//! before every jump into the firmware (issue 31, the design page's "Confirmation and the
//! watchdog"); the firmware only feeds it. The IWDG's counter runs only once the start key 0xCCCC
//! is written (or the "hardware watchdog" option bit is set; RM0090 Rev 18 §21.3), so a firmware
//! loaded without the bootloader (by probe, for debugging) runs unchanged and its reload writes
//! do nothing.

use stm32f4xx_hal::pac;

/// Reloads the IWDG's counter from its reload register (IWDG_KR = 0xAAAA, RM0090 Rev 18 §21.3.2, §21.4.1).
pub fn feed_watchdog() {
    // SAFETY: a write of the reload key to the IWDG's key register, a fixed address; it changes
    // nothing but the watchdog's counter, and no other code of the firmware touches the IWDG.
    let iwdg = unsafe { &*pac::IWDG::ptr() };
    iwdg.kr().write(|w| w.key().feed());
}
